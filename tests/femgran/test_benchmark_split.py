"""The time split of ``benchmarks/footing_speed.py --profile``: it must find the parts it names."""

import importlib.util
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "footing_speed.py"


@pytest.fixture(scope="module")
def footing_speed():
    spec = importlib.util.spec_from_file_location("footing_speed", _PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _split(footing_speed, soil):
    material = footing_speed._material(soil, 6000.0, 0.1)
    return footing_speed.timed_footing(material, True, resolution=1, steps=2, settlement_m=0.004)[2]


def test_the_profiled_split_puts_the_cpa_footings_time_in_its_material_update(footing_speed):
    """Each part is found (a wrong path or name would give 0 s), none exceeds the run, and the CPA law's
    material update takes a larger share of its footing than the Drucker-Prager cone's of its own."""
    cone = _split(footing_speed, "drucker-prager")
    cpa = _split(footing_speed, "cpa-isotropic")
    for split in (cone, cpa):
        assert set(split) == {*footing_speed.PARTS, "rest"}
        for part in footing_speed.PARTS:
            assert split[part] > 0.0, part
        assert split["rest"] >= 0.0
    share = {name: s["material update"] / sum(s.values()) for name, s in (("cone", cone), ("cpa", cpa))}
    assert share["cpa"] > share["cone"]
