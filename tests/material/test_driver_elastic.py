"""Element drivers against Hooke's law closed forms, path I/O and bad input (material.driver)."""

import numpy as np
import pytest

from material import LinearElastic, driver
from material.driver import LoadPath, PathFailure, mandel_rotation, run_path
from material.tensors import from_mandel, to_mandel
from material.tensors import to_mandel_matrix as tangent_to_mandel
from material.elastic import isotropic_stiffness
from material.results import read_csv

E, NU = 6000.0, 0.3
G = E / (2 * (1 + NU))
K = E / (3 * (1 - 2 * NU))


@pytest.fixture
def hooke():
    return LinearElastic(E, NU)


def _held(res, col, value):
    """Largest deviation of a stress column from its prescribed value, relative to the stress scale."""
    scale = np.abs(res.stress).max()
    return np.abs(res[col] - value).max() / scale


def test_mandel_round_trip_and_rotation(rng):
    a = rng.normal(size=(3, 3))
    a = a + a.T
    assert np.allclose(from_mandel(to_mandel(a)), a)
    c = isotropic_stiffness(E, NU)
    d = tangent_to_mandel(c)
    eps = rng.normal(size=(3, 3))
    eps = eps + eps.T
    assert np.allclose(d @ to_mandel(eps), to_mandel(np.einsum("ijkl,kl->ij", c, eps)))
    r = driver.rotation_about_z(30.0)
    assert np.allclose(mandel_rotation(r) @ to_mandel(a), to_mandel(r.T @ a @ r))


def test_triaxial_drained_matches_hooke(hooke):
    res = driver.triaxial(hooke, p0_kPa=100.0, axial_strain=0.01, steps=10)
    assert res.completed
    assert res["q_kPa"][-1] == pytest.approx(E * 0.01, rel=1e-9)  # q = E eps_a
    assert res["eps_r"][-1] == pytest.approx(-NU * 0.01, rel=1e-9)  # lateral strain -nu eps_a
    assert res["eps_v"][-1] == pytest.approx((1 - 2 * NU) * 0.01, rel=1e-9)
    for col in ("sig_xx_kPa", "sig_yy_kPa"):
        assert _held(res, col, -100.0) < 1e-8
    for col in ("sig_xz_kPa", "sig_yz_kPa", "sig_xy_kPa"):
        assert _held(res, col, 0.0) < 1e-8


def test_triaxial_extension_sign(hooke):
    res = driver.triaxial(hooke, p0_kPa=100.0, axial_strain=0.001, steps=2, extension=True)
    assert res["eps_a"][-1] == pytest.approx(-0.001)
    assert res["q_kPa"][-1] == pytest.approx(-E * 0.001, rel=1e-9)


def test_triaxial_undrained_pore_pressure(hooke):
    ea = 0.004
    res = driver.triaxial(hooke, p0_kPa=100.0, axial_strain=ea, steps=8, drained=False)
    assert np.abs(res["eps_v"]).max() < 1e-14  # constant volume
    assert res["q_kPa"][-1] == pytest.approx(3 * G * ea, rel=1e-9)  # undrained Young modulus 3G
    assert res["u_kPa"][-1] == pytest.approx(G * ea, rel=1e-9)  # du = q/3 (dp' = 0)
    assert res["p_kPa"][-1] == pytest.approx(100.0, rel=1e-12)
    total_lateral = res["sig_xx_kPa"] - res["u_kPa"]  # total stress (tension +) = sigma' - u
    assert _held(res, "sig_xx_kPa", -100.0 + res["u_kPa"]) < 1e-8
    assert np.allclose(total_lateral, -100.0, rtol=1e-10)


def test_oedometer_k0(hooke):
    res = driver.oedometer(hooke, p0_kPa=10.0, axial_strain=0.01, steps=5)
    assert res["K0_incremental"][-1] == pytest.approx(NU / (1 - NU), rel=1e-10)
    assert res["sigma_v_kPa"][-1] - 10.0 == pytest.approx((K + 4 * G / 3) * 0.01, rel=1e-10)


def test_direct_shear_closed_form(hooke):
    t, d = 0.006, 0.0006
    res = driver.direct_shear(hooke, sigma_n_kPa=50.0, shear_displacement=d, steps=4, band_thickness_m=t)
    assert res["tau_kPa"][-1] == pytest.approx(G * d / t, rel=1e-10)
    assert np.abs(res["normal_displacement_m"]).max() < 1e-15  # no dilation in Hooke simple shear
    assert _held(res, "sig_zz_kPa", -50.0) < 1e-8
    assert res["shear_displacement_m"][-1] == pytest.approx(d)


def test_plane_strain_and_true_triaxial(hooke):
    res = driver.plane_strain(hooke, p0_kPa=50.0, axial_strain=0.01, steps=3)
    # eps_yy = 0 -> d sigma_yy = nu (d sigma_zz) with sigma_xx held
    dzz = res["sig_zz_kPa"][-1] + 50.0
    assert res["sig_yy_kPa"][-1] + 50.0 == pytest.approx(NU * dzz, rel=1e-10)
    assert np.abs(res["eps_yy"]).max() < 1e-15
    # Rice's condition on every step's tangent: Hooke's closed form in the plane, no band
    assert np.allclose(res["rice_indicator"], 4 * (1 - 2 * NU) * (1 - NU) / ((1 - 2 * NU) ** 2 + 4 * (1 - NU) ** 2))
    assert res.metadata["bifurcation"] is None and res.tangent.shape == (4, 3, 3, 3, 3)
    res = driver.true_triaxial(hooke, p0_kPa=50.0, b=0.25, axial_strain=0.01, steps=3)
    s = -res.stress[-1].diagonal()
    assert (s[1] - s[0]) / (s[2] - s[0]) == pytest.approx(0.25, rel=1e-10)
    assert _held(res, "sig_xx_kPa", -50.0) < 1e-8


def test_rotation_reshear_principal_direction(hooke):
    res = driver.rotation(hooke, p0_kPa=14.0, delta_psi_deg=45.0, preshear_strain=0.001, axial_strain=0.002, steps=4)
    assert res.completed
    s = res.stress[-1]
    w, v = np.linalg.eigh(s[:2, :2])
    major = v[:, 0]  # most compressive (tension +: smallest eigenvalue)
    assert abs(abs(major @ np.array([1.0, 1.0]) / np.sqrt(2))) == pytest.approx(1.0, abs=1e-10)
    # the unload stage returns to hydrostatic
    unload_end = np.flatnonzero(res["stage"] == 1)[-1]
    assert np.allclose(res.stress[unload_end], -14.0 * np.eye(3), rtol=0, atol=1e-8 * 14.0)
    assert np.abs(res["eps_zz"]).max() < 1e-15


def test_cyclic_simple_shear_returns_to_zero(hooke):
    res = driver.cyclic_simple_shear(hooke, gamma_amplitude=0.001, cycles=2, steps_per_quarter=3)
    assert res["gamma"][-1] == pytest.approx(0.0, abs=1e-15)
    assert res["gamma"].max() == pytest.approx(0.001)
    assert res["tau_kPa"][-1] == pytest.approx(0.0, abs=1e-9)


def test_csv_path_round_trip(hooke, tmp_path):
    # a triaxial test written as lab data: strain on z, stresses on the others
    n = 6
    ezz = -np.linspace(0.0, 0.003, n)
    rows = ["# lab data, tension +", "step,sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_xy_kPa"]
    rows += [f"{i},-80,-80,{float(ezz[i])!r},0,0,0" for i in range(n)]
    f = tmp_path / "lab.csv"
    f.write_text("\n".join(rows) + "\n")
    path = LoadPath.from_csv(f, substeps=2)
    assert path.n_steps == 2 * (n - 1)
    assert np.allclose(path.initial_stress, -80 * np.eye(3))
    res = run_path(hooke, path)
    ref = driver.triaxial(hooke, p0_kPa=80.0, axial_strain=0.003, steps=5)
    assert np.allclose(res.stress[::2], ref.stress, rtol=0, atol=1e-9)
    out = res.to_csv(tmp_path / "res.csv")
    back = read_csv(out)
    assert back.columns == res.columns
    assert np.allclose(back["q_kPa"], res["q_kPa"], rtol=1e-10)
    assert np.allclose(back.stress, res.stress, rtol=1e-10)
    assert back.metadata["material"] == repr(hooke)
    header = out.read_text().splitlines()[:8]
    assert any("tension positive" in h for h in header)


def test_plot_returns_figure(hooke):
    from matplotlib.figure import Figure

    res = driver.triaxial(hooke, axial_strain=0.001, steps=2)
    fig = res.plot()
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 2
    with pytest.raises(KeyError, match="no column 'nope'"):
        res.plot([("eps_a", "nope")])


class _Brittle:
    """Hooke until |eps_zz| exceeds a limit, then FAILED: exercises cut-backs and the partial table."""

    def __init__(self, limit):
        self.inner = LinearElastic(E, NU)
        self.limit = limit

    def initial_state(self, n, stress=None, *, element_size=None):
        return self.inner.initial_state(n, stress)

    def update(self, de, s, st):
        s1, st1, c = self.inner.update(de, s, st)
        if abs(st1["strain"][0, 2, 2]) > self.limit:
            st1["status"][:] = 2
            s1 = np.array(s)
        return s1, st1, c


def test_failure_keeps_partial_table():
    with pytest.warns(RuntimeWarning, match="step 4"):
        res = driver.triaxial(_Brittle(0.0035), axial_strain=0.01, steps=10, max_cuts=2)
    assert not res.completed
    assert "step 4" in res.message and "FAILED" in res.message
    assert len(res) == 4  # start + 3 converged steps
    with pytest.raises(PathFailure) as info:
        driver.triaxial(_Brittle(0.0035), axial_strain=0.01, steps=10, on_failure="raise")
    assert len(info.value.result) == 4


def test_cutback_recovers_step():
    # one step too large for a law that fails for increments > 0.0015: cut-backs finish it
    class Picky(_Brittle):
        def update(self, de, s, st):
            s1, st1, c = self.inner.update(de, s, st)
            if np.abs(de).max() > 0.0015:
                st1["status"][:] = 2
                s1 = np.array(s)
            return s1, st1, c

    res = driver.triaxial(Picky(1.0), axial_strain=0.004, steps=2)
    assert res.completed
    assert res["cuts"].max() >= 1
    assert res["q_kPa"][-1] == pytest.approx(E * 0.004, rel=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"p0_kPa": -1.0}, "p0_kPa"),
        ({"p0_kPa": float("nan")}, "p0_kPa"),
        ({"steps": 0}, "steps"),
        ({"axial_strain": 0.0}, "axial_strain"),
        ({"rule": "bazant-oh-33"}, "rule"),
    ],
)
def test_triaxial_bad_input(hooke, kwargs, match):
    with pytest.raises(ValueError, match=match):
        driver.triaxial(hooke, **kwargs)


def test_bad_model_and_options(hooke):
    with pytest.raises(ValueError, match="material object"):
        driver.triaxial(object())
    with pytest.raises(ValueError, match="b = 1.5"):
        driver.true_triaxial(hooke, b=1.5)
    with pytest.raises(ValueError, match="on_failure"):
        driver.triaxial(hooke, steps=1, on_failure="ignore")
    with pytest.raises(ValueError, match="lateral"):
        driver.simple_shear(hooke, lateral="free")


def test_load_path_bad_components():
    path = LoadPath()
    with pytest.raises(KeyError, match="sig_zx"):
        path.add(1, sig_zx=0.0)
    with pytest.raises(ValueError, match="'yz'.*neither"):
        path.add(1, sig_xx=0, sig_yy=0, eps_zz=0, sig_xz=0, sig_xy=0)
    with pytest.raises(ValueError, match="'xx'.*both"):
        path.add(1, sig_xx=0, eps_xx=0, sig_yy=0, eps_zz=0, sig_yz=0, sig_xz=0, sig_xy=0)
    with pytest.raises(ValueError, match="finite"):
        path.add(1, sig_xx=float("nan"), sig_yy=0, eps_zz=0, sig_yz=0, sig_xz=0, sig_xy=0)
    with pytest.raises(ValueError, match="no segments"):
        run_path(LinearElastic(E, NU), LoadPath())
    with pytest.raises(ValueError, match="initial_stress"):
        LoadPath(initial_stress=np.ones((2, 2)))


@pytest.mark.parametrize(
    "text, exc, match",
    [
        ("sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_qq_kPa\n0,0,0,0,0,0\n0,0,0,0,0,0\n", KeyError, "sig_qq_kPa"),
        ("sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa\n0,0,0,0,0\n0,0,0,0,0\n", ValueError, r"\['xy'\]"),
        ("sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_xy_kPa\n0,0,0,0,0,0\n0,0,nan,0,0,0\n", ValueError, "NaN"),
        ("sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_xy_kPa\n0,0,0,0,0,0\n0,0,0,0,0\n", ValueError, "row 2 has 5 values"),
        ("sig_xx_kPa,eps_xx,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_xy_kPa\n0,0,0,0,0,0,0\n0,0,0,0,0,0,0\n", ValueError, "twice"),
        ("sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_xy_kPa\n0,0,0,0,0,0\n", ValueError, "at least two"),
    ],
)
def test_csv_path_bad_input(tmp_path, text, exc, match):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(exc, match=match):
        LoadPath.from_csv(f)


def test_csv_path_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothere.csv"):
        LoadPath.from_csv(tmp_path / "nothere.csv")


def test_log_written_step_by_step(hooke, tmp_path):
    log = tmp_path / "steps.csv"
    res = driver.triaxial(hooke, p0_kPa=100.0, axial_strain=0.001, steps=4, log=log)
    from material.table import read_table

    data = read_table(log)
    assert len(data) == 5 and len(data.columns) == 15
    np.testing.assert_array_equal(data["sig_zz_kPa"], res["sig_zz_kPa"])  # 17 digits: the same numbers
    np.testing.assert_array_equal(data["eps_xx"], res["eps_xx"])


def test_undrained_needs_a_normal_stress_condition():
    with pytest.raises(ValueError, match="undrained segment"):
        LoadPath().add(1, eps_xx=0, eps_yy=0, eps_zz=-0.01, sig_yz=0, sig_xz=0, sig_xy=0, undrained=True)


def test_toml_path_matches_drivers(hooke, tmp_path):
    f = tmp_path / "path.toml"
    f.write_text(
        "p0_kPa = 100.0\n"
        "[[segment]]\nname = 'undrained'\nsteps = 4\nundrained = true\n"
        "eps_zz = -0.004\nsig_xx = -100.0\nsig_yy = -100.0\nsig_yz = 0.0\nsig_xz = 0.0\nsig_xy = 0.0\n"
        "[[segment]]\nsteps = 2\nframe_z_deg = 30.0\n"
        "eps_xx = -0.001\nsig_yy = -100.0\nsig_xy = 0.0\neps_zz = 0.0\nsig_yz = 0.0\nsig_xz = 0.0\n"
    )
    path = LoadPath.from_toml(f)
    assert [s.name for s in path.segments] == ["undrained", "segment 1"]
    res = run_path(hooke, path)
    ref = driver.triaxial(hooke, p0_kPa=100.0, axial_strain=0.004, steps=4, drained=False)
    assert np.allclose(res.stress[:5], ref.stress, rtol=0, atol=1e-9)
    assert res["u_kPa"][4] == pytest.approx(G * 0.004, rel=1e-9)
    r = driver.rotation_about_z(30.0)
    s_rot = r.T @ res.stress[-1] @ r
    assert s_rot[0, 1] == pytest.approx(0.0, abs=1e-8 * 100)


@pytest.mark.parametrize(
    "text, exc, match",
    [
        ("p0 = 1\n[[segment]]\nsteps = 1\n", KeyError, "p0"),
        ("p0_kPa = 1\n", ValueError, "no \\[\\[segment\\]\\]"),
        ("[[segment]]\nsteps = 1\nsig_xx = 0\nsig_yy = 0\nsig_zz = 0\nsig_yz = 0\nsig_xz = 0\nsig_xy = 0\ncolour = 1\n",
         KeyError, "colour"),
        ("[[segment]]\nsig_xx = 0\n", ValueError, "missing 'steps'"),
        ("[[segment]]\nsteps = 1\nsig_xx = 0\n", ValueError, "segment 0: component 'yy'"),
        ("[[segment\n", ValueError, "not valid TOML"),
    ],
)
def test_toml_path_bad_input(tmp_path, text, exc, match):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(exc, match=match):
        LoadPath.from_toml(f)
