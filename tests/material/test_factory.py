"""One material factory for the drivers, the cases and the command line, with one rule for alpha_deg."""

import numpy as np
import pytest

from material import CPAModel, DruckerPrager, MohrCoulomb, driver, load_preset, save_parameters
from material.anisotropy import axes_from_alpha
from material.factory import make_material, plane_strain_axes


@pytest.mark.parametrize("plane_strain, expected_e2", [(False, [0.5, 0.0, np.sqrt(3) / 2]),
                                                       (True, [0.5, np.sqrt(3) / 2, 0.0])])
def test_every_spec_of_a_cpa_law_builds_it_with_the_axes_of_alpha(tmp_path, plane_strain, expected_e2):
    params = load_preset("ottawa_c109").replace(beta=2.0)
    path = save_parameters(params, tmp_path / "sand.toml")
    for spec, want in [(None, load_preset("ottawa_c109")), ("ottawa_c109", load_preset("ottawa_c109")),
                       (params, params), (path, params), (str(path), params)]:
        model = make_material(spec, alpha_deg=30.0, plane_strain=plane_strain, stabilisation=0.1)
        assert isinstance(model, CPAModel) and model.params == want
        np.testing.assert_allclose(model.axes[:, 1], expected_e2, atol=1e-12)
        assert model.options.stabilisation == 0.1


def test_a_material_object_is_used_as_it_is_and_alpha_must_match_its_axes():
    model = CPAModel("ottawa_c109", axes=plane_strain_axes(30.0))
    assert make_material(model, plane_strain=True) is model
    assert make_material(model, alpha_deg=30.0, plane_strain=True) is model
    with pytest.raises(ValueError, match=r"alpha_deg = 0.0 does not match the material's own axes"):
        make_material(model, alpha_deg=0.0, plane_strain=True)
    with pytest.raises(ValueError, match=r"alpha_deg = 30.0 does not match"):
        make_material(model, alpha_deg=30.0, plane_strain=False)  # same angle, other frame
    with pytest.raises(ValueError, match=r"stabilisation = 0.1: applies to a CPA law built from a preset"):
        make_material(model, stabilisation=0.1)
    with pytest.raises(ValueError, match=r"relaxation_time = 0.05: applies to a CPA law built from a preset"):
        make_material(model, relaxation_time=0.05)
    dp = DruckerPrager(30000, 0.3, cohesion_kPa=1.0, friction_deg=30.0)
    assert make_material(dp, alpha_deg=45.0) is dp  # no axes: alpha is only recorded


def test_the_drivers_and_the_cases_apply_the_same_rule():
    from femgran.cases import element, footing

    model = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0))
    message = r"alpha_deg = 0.0 does not match the material's own axes"
    with pytest.raises(ValueError, match=message):
        driver.triaxial(model, 100.0, 0.0, axial_strain=0.001, steps=1)
    with pytest.raises(ValueError, match=message):
        element(model, alpha_deg=0.0, steps=1)
    with pytest.raises(ValueError, match=message):
        footing(CPAModel("ottawa_c109", axes=plane_strain_axes(30.0)), alpha_deg=0.0, resolution=1, steps=1)


@pytest.mark.parametrize("spec", [3.0, object(), "no_such_preset"])
def test_a_bad_material_spec_is_named(spec):
    with pytest.raises((ValueError, KeyError), match="material = |no_such_preset"):
        make_material(spec)


def test_replace_keeps_the_options_and_with_replay_dir_copies(tmp_path):
    model = CPAModel("ottawa_c109", axes=plane_strain_axes(20.0), stabilisation=0.1, regularise=False)
    weak = model.replace(params=model.params.replace(eta0=0.5))
    assert weak.params.eta0 == 0.5 and weak.options == model.options and weak.regularise is False
    np.testing.assert_array_equal(weak.axes, model.axes)
    kept = model.with_replay_dir(tmp_path)
    assert kept.replay_dir == tmp_path and model.replay_dir is None


def test_a_mapping_is_the_material_table_of_a_case_file(tmp_path):
    model = make_material({"preset": "ottawa_c109", "stabilisation": 0.1, "set": {"beta": 5.0, "b": 0.1}},
                          alpha_deg=30.0, plane_strain=True)
    assert model.options.stabilisation == 0.1 and model.params.beta == 5.0 and model.params.b == (0.1,)
    assert model.relaxation_time is None
    assert make_material({"stabilisation": 0.1, "relaxation_time": 0.025}).relaxation_time == 0.025
    np.testing.assert_allclose(model.axes[:, 1], plane_strain_axes(30.0)[:, 1])
    dp = make_material({"law": "drucker_prager", "E_kPa": 3e4, "nu": 0.3, "cohesion_kPa": 1.0, "friction_deg": 30.0})
    assert isinstance(dp, DruckerPrager)
    mc = make_material({"law": "mohr_coulomb", "E_kPa": 6e3, "nu": 0.3, "cohesion_kPa": 0.0, "friction_deg": 30.0,
                        "dilation_deg": 10.0})
    assert isinstance(mc, MohrCoulomb) and (mc.friction_deg, mc.dilation_deg) == (30.0, 10.0)
    with pytest.raises(ValueError, match=r"\(law 'mohr_coulomb'\): unknown key\(s\) \['match'\]; allowed"):
        make_material({"law": "mohr_coulomb", "match": "plane_strain"})
    with pytest.raises(ValueError, match=r"\(law 'von_mises'\): unknown key\(s\) \['phi'\]; allowed"):
        make_material({"law": "von_mises", "phi": 3})
