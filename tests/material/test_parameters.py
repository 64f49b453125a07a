"""CPAParameters: validation of every field, presets, TOML/JSON round trips, file errors."""

import json
import math

import pytest

from material import CPAParameters, load_parameters, load_preset, save_parameters
from material.parameters import FIELD_NAMES, PRESETS, UNITS, parameters_from_dict

BASE = dict(E=6000.0, nu=0.33, t=0.006, A=1.58e-4, eta0=0.8896)

# (field, invalid value, fragment of the allowed range printed in the message)
INVALID = [
    ("E", 0.0, "E > 0"), ("E", -10.0, "E > 0"), ("E", math.inf, "E > 0"), ("E", math.nan, "E > 0"),
    ("nu", -1.0, "-1 < nu < 0.5"), ("nu", 0.5, "-1 < nu < 0.5"), ("nu", math.nan, "-1 < nu < 0.5"),
    ("t", 0.0, "t > 0"), ("t", math.inf, "t > 0"),
    ("A", 0.0, "A > 0"), ("A", -1e-4, "A > 0"),
    ("eta0", 0.0, "eta0 > 0"), ("eta0", -0.5, "eta0 > 0"),
    ("omega1", 0.5, "-0.5 < omega1 < 0.5"), ("omega1", -0.5, "-0.5 < omega1 < 0.5"),
    ("eta_c_ratio", -0.01, "0 <= eta_c_ratio <= 1"), ("eta_c_ratio", 1.01, "0 <= eta_c_ratio <= 1"),
    ("c0", -1.0, "c0 >= 0"), ("c0", math.inf, "c0 >= 0"),
    ("omega1_c", 0.6, "-0.5 < omega1_c < 0.5"),
    ("zeta", 0.99, "1 <= zeta <= 2"), ("zeta", 2.5, "1 <= zeta <= 2"),
    ("beta", -0.1, "0 <= beta"), ("beta", math.inf, "0 <= beta"),
    ("alpha_hat", -0.1, "0 <= alpha_hat"), ("alpha_hat", math.nan, "0 <= alpha_hat"),
    ("beta_hat", math.inf, "finite"),
    ("softening_slip", -1e-3, "softening_slip >= 0"), ("softening_slip", math.inf, "softening_slip >= 0"),
    ("residual_ratio", 0.0, "0 < residual_ratio <= 1"), ("residual_ratio", 1.2, "0 < residual_ratio <= 1"),
    ("apex_stress", 0.0, "apex_stress > 0"), ("apex_stress", -0.05, "apex_stress > 0"),
    ("apex_stress", math.inf, "apex_stress > 0"),
    ("compaction_stress", -1.0, "compaction_stress >= 0"), ("compaction_stress", math.nan, "compaction_stress >= 0"),
]


def test_softening_needs_a_finite_peak_slip():
    with pytest.raises(ValueError, match="'softening_slip' = 0.001 needs 'zeta' > 1"):
        CPAParameters(**BASE, softening_slip=1e-3)
    p = CPAParameters(**{**BASE, "zeta": 1.05}, softening_slip=1e-3)
    assert p.kappa_instability == pytest.approx(p.A / 0.05)


def test_coaxial_law_needs_a_direction():
    with pytest.raises(ValueError, match="'alpha_hat' = 0 and 'beta_hat' = 0"):
        CPAParameters(**BASE, beta=1.0, alpha_hat=0.0, beta_hat=0.0)
    CPAParameters(**BASE, beta=0.0, alpha_hat=0.0, beta_hat=0.0)  # no induced anisotropy: fine


@pytest.mark.parametrize("key,value,allowed", INVALID)
def test_invalid_value_names_key_value_and_range(key, value, allowed):
    with pytest.raises(ValueError) as exc:
        CPAParameters(**{**BASE, key: value})
    msg = str(exc.value)
    assert repr(key) in msg and repr(float(value)) in msg and allowed in msg
    # replace() validates too
    with pytest.raises(ValueError, match=repr(key)):
        load_preset("ottawa_c109").replace(**{key: value})


def test_every_scalar_field_is_covered_by_a_check():
    scalar = [f for f in FIELD_NAMES if f not in ("a", "b", "name")]
    assert sorted({k for k, _, _ in INVALID}) == sorted(scalar)
    assert set(UNITS) == set(FIELD_NAMES) - {"name"}


@pytest.mark.parametrize("key", ["a", "b"])
@pytest.mark.parametrize("value", [5.0, "12", ["x"], None])
def test_invalid_coefficient_sequences(key, value):
    with pytest.raises(ValueError, match=f"parameter '{key}'"):
        CPAParameters(**{**BASE, key: value})


@pytest.mark.parametrize("key", ["a", "b"])
def test_non_finite_coefficient(key):
    with pytest.raises(ValueError, match=rf"'{key}'\[1\] = nan"):
        CPAParameters(**{**BASE, key: (0.1, math.nan)})


@pytest.mark.parametrize("value", ["6000", True, None, [1.0]])
def test_non_numbers_rejected(value):
    with pytest.raises(ValueError, match="'E'.*must be a number"):
        CPAParameters(**{**BASE, "E": value})


def test_valid_edges_accepted_and_converted():
    p = CPAParameters(**{**BASE, "E": 6000, "eta_c_ratio": 0.0, "zeta": 1.0, "a": [1, 2]})
    assert isinstance(p.E, float) and p.a == (1.0, 2.0)
    assert CPAParameters(**{**BASE, "eta_c_ratio": 1.0, "zeta": 2.0, "nu": -0.99}).zeta == 2.0


def test_presets_match_the_thesis():
    p = load_preset("ottawa_c109")  # Table 3 / eq. 2.21
    assert (p.E, p.nu, p.t, p.A, p.eta0, p.omega1) == (6000.0, 0.33, 0.006, 1.58e-4, 0.8896, 0.1398)
    assert p.a == (0.3956, 0.4457, 18.96) and p.eta_c_ratio == 0.65 and p.c0 == 0 and p.zeta == 1 and p.beta == 0
    q = load_preset("ottawa_c109_induced")  # section 3.5
    assert (q.eta0, q.A, q.omega1, q.beta) == (0.89, 1.0e-4, 0.0, 0.1)
    assert set(PRESETS) == {"ottawa_c109", "ottawa_c109_induced"}


def test_derived_moduli():
    p = load_preset("ottawa_c109")
    assert p.shear_modulus == pytest.approx(6000 / 2.66)
    assert p.bulk_modulus == pytest.approx(6000 / (3 * 0.34))
    assert p.kappa_instability == math.inf
    assert p.replace(zeta=1.05).kappa_instability == pytest.approx(1.58e-4 / 0.05)


def test_unknown_preset_and_unknown_keys():
    with pytest.raises(KeyError, match="ottawa_c109"):
        load_preset("toyoura")
    with pytest.raises(KeyError, match="friction"):
        load_preset("ottawa_c109").replace(friction=0.5)
    with pytest.raises(KeyError, match="unknown parameter key"):
        parameters_from_dict({"parameters": {**BASE, "Young": 1.0}})
    with pytest.raises(KeyError, match="missing required"):
        parameters_from_dict({"parameters": {"E": 1.0}})
    with pytest.raises(KeyError, match="unknown preset"):
        parameters_from_dict({"parameters": {"preset": "nope"}})


def test_replace_is_immutable_copy():
    p = load_preset("ottawa_c109")
    q = p.replace(beta=5.0)
    assert q.beta == 5.0 and p.beta == 0.0 and q.name == "ottawa_c109"
    with pytest.raises(Exception):
        p.beta = 1.0  # frozen


@pytest.mark.parametrize("suffix", [".toml", ".json"])
@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_file_round_trip(tmp_path, suffix, preset):
    p = load_preset(preset).replace(c0=0.5, omega1_c=0.1, b=(0.2,), zeta=1.02)
    path = save_parameters(p, tmp_path / f"params{suffix}", seed=7, version="0.1")
    q = load_parameters(path)
    assert q == p and q.name == p.name and q.a == p.a and q.b == p.b
    text = path.read_text()
    assert "units" in text and "seed" in text


def test_file_with_preset_override_and_flat_layout(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[parameters]\npreset = "ottawa_c109"\nbeta = 5.0\n')
    p = load_parameters(f)
    assert p.beta == 5.0 and p.eta0 == 0.8896
    g = tmp_path / "flat.json"
    g.write_text(json.dumps(BASE))
    assert load_parameters(g).E == 6000.0
    h = tmp_path / "bad.toml"
    h.write_text('[parameters]\npreset = "ottawa_c109"\nnu = 0.7\n')
    with pytest.raises(ValueError, match="'nu' = 0.7"):
        load_parameters(h)


def test_file_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_parameters(tmp_path / "missing.toml")
    bad = tmp_path / "x.yaml"
    bad.write_text("E: 1")
    with pytest.raises(ValueError, match="suffix"):
        load_parameters(bad)
    with pytest.raises(ValueError, match="suffix"):
        save_parameters(load_preset("ottawa_c109"), tmp_path / "x.yaml")
    broken = tmp_path / "broken.toml"
    broken.write_text("[parameters\nE = ")
    with pytest.raises(ValueError, match="could not be parsed"):
        load_parameters(broken)
    unknown = tmp_path / "unknown.json"
    unknown.write_text(json.dumps({"parameters": {**BASE, "phi": 30}}))
    with pytest.raises(KeyError, match="phi"):
        load_parameters(unknown)
