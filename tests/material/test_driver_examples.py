"""Run each examples/element_*.py (coarse) and assert one number."""

import warnings

import pytest



def test_element_01_triaxial(tmp_path, load_example):
    peaks = load_example("element_01_triaxial").main(out=tmp_path, steps=60)
    assert peaks[(100.0, 0.0)] > 1.25 * peaks[(100.0, 90.0)]
    assert (tmp_path / "triaxial.png").is_file()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_element_02_direct_shear(tmp_path, load_example):
    runs = load_example("element_02_direct_shear").main(out=tmp_path, steps=150)
    assert runs[0.0]["tau_over_sigma_n"].max() == pytest.approx(0.763, abs=0.01)


def test_element_03_rotation(tmp_path, load_example):
    peaks = load_example("element_03_rotation").main(out=tmp_path, steps=40)
    assert peaks[(10.0, 0.0)] - peaks[(10.0, 90.0)] > peaks[(0.1, 0.0)] - peaks[(0.1, 90.0)] + 10.0
