"""Identification of friction, offsets and payload, and the collision thresholds they suggest."""
