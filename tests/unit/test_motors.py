"""The motor catalogue: lookups, required models, overrides from YAML."""

from __future__ import annotations

import pytest

from akarm import ConfigError, UnknownMotorError
from akarm.protocol import motors
from akarm.protocol.motors import Catalogue, MotorModel

REQUIRED = ["AK10-9", "AK60-6", "AK70-10", "AK80-6", "AK80-9", "AK80-64",
            "AK80-8", "AK70-9", "AK45-10", "AK45-36", "AK40-10"]


@pytest.mark.parametrize("name", REQUIRED)
def test_required_models_present_with_complete_mit_ranges(name: str) -> None:
    m = motors.get(name)
    assert m.name == name
    assert m.p_max > 0 and m.v_max > 0 and m.t_max > 0
    assert m.kp_max == 500.0 and m.kd_max == 5.0
    assert m.gear_ratio > 1 and m.pole_pairs > 0
    assert m.servo_position in ("output", "rotor")
    assert m.source


def test_manual_mit_ranges_match_the_protocol_notes() -> None:
    table = {"AK10-9": (12.5, 50, 65), "AK60-6": (12.5, 45, 15), "AK70-10": (12.5, 50, 25),
             "AK80-6": (12.5, 76, 12), "AK80-9": (12.5, 50, 18), "AK80-64": (12.5, 8, 144)}
    for name, (p, v, t) in table.items():
        m = motors.get(name)
        assert (m.p_max, m.v_max, m.t_max) == (p, v, t), name


def test_lookup_is_case_insensitive_and_passes_models_through() -> None:
    m = motors.get("ak80-9")
    assert m is motors.get("AK80-9") is motors.get("  Ak80-9 ")
    assert motors.get(m) is m


def test_unknown_model_lists_the_known_ones() -> None:
    with pytest.raises(UnknownMotorError) as info:
        motors.get("AK99-1")
    text = str(info.value)
    assert "AK99-1" in text and "AK80-9" in text and "AK10-9" in text
    assert isinstance(info.value, KeyError)


def test_variant_entries_inherit_from_their_base() -> None:
    v3 = motors.get("AK10-9-V3")
    base = motors.get("AK10-9")
    assert (v3.p_max, v3.v_max, v3.t_max, v3.firmware) == (12.56, 28.0, 54.0, "v3")
    assert v3.gear_ratio == base.gear_ratio and v3.kt == base.kt


def test_override_changes_only_given_fields_and_adds_new_models(tmp_path) -> None:
    f = tmp_path / "mine.yaml"
    f.write_text("AK80-9: {v_max: 25.64}\nMY-MOTOR: {base: AK60-6, t_max: 20}\n"
                 "BARE: {p_max: 12.5, v_max: 10, t_max: 5, gear_ratio: 3, pole_pairs: 7}\n")
    cat = motors.default_catalogue().extended(__import__("yaml").safe_load(f.read_text()), str(f))
    assert cat.get("ak80-9").v_max == 25.64 and cat.get("ak80-9").t_max == 18.0
    assert cat.get("my-motor").t_max == 20.0 and cat.get("my-motor").gear_ratio == 6.0
    assert cat.get("bare").kt is None and cat.get("bare").kp_max == 500.0
    assert motors.get("AK80-9").v_max == 50.0  # the default catalogue is untouched


def test_load_changes_the_process_catalogue(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(motors, "_default", None)
    f = tmp_path / "fw.yaml"
    f.write_text("AK70-10: {t_max: 30}\n")
    motors.load(f)
    assert motors.get("AK70-10").t_max == 30.0
    monkeypatch.setattr(motors, "_default", None)
    assert motors.get("AK70-10").t_max == 25.0


def test_environment_variable_names_an_override_file(tmp_path, monkeypatch) -> None:
    f = tmp_path / "env.yaml"
    f.write_text("AK45-10: {v_max: 22}\n")
    monkeypatch.setattr(motors, "_default", None)
    monkeypatch.setenv("AKARM_MOTORS", str(f))
    assert motors.get("AK45-10").v_max == 22.0
    monkeypatch.setattr(motors, "_default", None)


def test_bad_entries_report_every_problem() -> None:
    with pytest.raises(ConfigError) as info:
        Catalogue().extended({"X": {"p_max": -1, "v_maxx": 3, "servo_position": "shaft"}}, "f.yaml")
    msgs = [p.message for p in info.value.problems]
    assert any("p_max must be a positive finite number" in m for m in msgs)
    assert any("unknown motor field 'v_maxx'" in m and "did you mean 'v_max'" in m for m in msgs)
    assert any("servo_position must be one of output, rotor" in m for m in msgs)
    assert any("lacks 'gear_ratio'" in m for m in msgs)
    assert all(p.file == "f.yaml" for p in info.value.problems)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("t_max", float("inf"), "t_max must be a positive finite number, got inf"),
    ("p_max", float("inf"), "p_max must be a positive finite number"),
    ("gear_ratio", float("inf"), "gear_ratio must be a positive finite number"),
    ("v_max", float("nan"), "v_max must be a positive finite number, got nan"),
    ("pole_pairs", float("inf"), "pole_pairs must be a positive finite number"),
    ("pole_pairs", 1.5, "pole_pairs must be a whole number, got 1.5"),
    ("mit_temp_offset", float("nan"), "mit_temp_offset must be a finite number, got nan"),
    ("mit_temp_offset", float("-inf"), "mit_temp_offset must be a finite number"),
    ("source", 5, "source must be text"),
])
def test_a_variant_with_an_infinite_nan_or_fractional_value_is_refused(field: str, value: object,
                                                                         message: str) -> None:
    """An infinite range or limit made every command or reading NaN (the arm enabled, its torque NaN);
    a NaN temperature offset made the over-temperature stop impossible; 1.5 pole pairs became 1."""
    with pytest.raises(ConfigError) as info:
        motors.default_catalogue().extended({"AK80-9": {field: value}}, "m.yaml")
    (problem,) = info.value.problems
    assert problem.message.startswith(f"motor 'AK80-9': {message}"), problem.message
    fine = motors.default_catalogue().extended({"AK80-9": {"pole_pairs": 21.0, "mit_temp_offset": -40}}, "m.yaml")
    assert fine.get("AK80-9").pole_pairs == 21 and fine.get("AK80-9").mit_temp_offset == -40


def test_unknown_base_is_a_config_problem() -> None:
    with pytest.raises(ConfigError, match="unknown motor model 'AK00'"):
        motors.default_catalogue().extended({"X": {"base": "AK00"}})


def test_derived_quantities() -> None:
    m = motors.get("AK80-9")
    assert isinstance(m, MotorModel)
    assert m.output_kt == pytest.approx(0.091 * 9)
    assert m.reflected_inertia == pytest.approx(6.1e-5 * 81)
