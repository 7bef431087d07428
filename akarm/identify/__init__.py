"""Identification of friction, offsets and payload, and the collision thresholds they suggest.

- :mod:`akarm.identify.fit`: the arithmetic, pure (excitation, regressor fits, thresholds, results).
- :mod:`akarm.identify.procedure`: driving an :class:`~akarm.Arm` through it, by its public API only.

::

    import akarm.identify
    result = akarm.identify.identify(arm)            # an enabled arm, holding still
    payload = akarm.identify.estimate_payload(arm)
    # a real unit's torque scale, with a known weight hung at the tool half-way (hang(True), hang(False))
    result = akarm.identify.identify_unit(arm, (0.5, (0.04, 0.0, 0.05)), hang)
"""

from __future__ import annotations

from akarm.identify.fit import Identification, JointFit, PayloadFit
from akarm.identify.procedure import apply_identification, estimate_payload, identify, identify_unit

__all__ = ["Identification", "JointFit", "PayloadFit", "apply_identification", "estimate_payload", "identify",
           "identify_unit"]
