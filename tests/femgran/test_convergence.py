"""Mesh convergence of a softening study (femgran.convergence): the spread of q, the band against the finest mesh."""

import numpy as np
import pytest

from femgran.convergence import band_spread, describe, q_spread
from material.table import Table

W, H = 0.05, 0.1
STEPS = 20  # axial strain 0.001 per step; the peak at step 2, then windows of 0.005 to 0.7, 1.2, 1.7 and 2.0 %


def _history(peak, softening, end=STEPS):
    e = 0.001 * np.arange(end + 1)
    q = np.where(e <= 0.002, peak * e / 0.002, peak - softening * (e - 0.002))
    return Table({"load_factor": e / (0.001 * STEPS), "eps_a": e, "q_kPa": q})


def test_the_spread_of_q_is_taken_from_the_latest_peak_to_the_earliest_end():
    """Three straight softening branches: 400 - 1000 (e - 0.002), 402 - 900 (e - 0.002) and
    398 - 1000 (e - 0.002) to e = 0.015; from the peak at 0.2 % to 1.5 % their spread grows from 4 kPa to
    4 + 100 x 0.013 = 5.3 kPa, 1.32 % of the largest peak, at the end of the shortest run."""
    runs = [_history(400.0, 1000.0), _history(402.0, 900.0), _history(398.0, 1000.0, end=15)]
    table = q_spread(runs)
    assert table["eps_a"][0] == pytest.approx(0.002) and table["eps_a"][-1] == pytest.approx(0.015)
    assert table["spread_kPa"][0] == pytest.approx(4.0)
    assert table["spread_kPa"][-1] == pytest.approx(5.3)
    assert table["spread_of_peak"].max() == pytest.approx(5.3 / 402.0)
    assert table.metadata["peak_q_kPa"] == 402.0
    assert describe(q=table).startswith("q spreads by at most 1.32 % of the peak (5.3 kPa at 1.50 %) "
                                        "from 0.20 to 1.50 %")
    with pytest.raises(ValueError, match="at least two runs"):
        q_spread(runs[:1])
    with pytest.raises(ValueError, match="history 1: eps_a must increase"):
        q_spread([runs[0], Table({"eps_a": [0.0, 0.002, 0.001], "q_kPa": [0.0, 1.0, 2.0]})])


def _run_folder(folder, n, thickness_mm, angle_deg=60.0):
    """A synthetic plane run on n x 2n square cells: its VTK series (cell field ``strain``, a deviatoric
    strain whose increments in window j lie in a Gaussian band of full width at half maximum
    ``thickness_mm[j]`` at ``angle_deg`` through the centre, on a background of a fifth of its height) and
    its history."""
    import meshio

    folder.mkdir(parents=True)
    h = W / n
    xs, ys = np.meshgrid(np.linspace(0.0, W, n + 1), np.linspace(0.0, H, 2 * n + 1), indexing="ij")
    points = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    idx = np.arange(xs.size).reshape(xs.shape)
    quads = np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()])
    centres = points[quads].mean(axis=1)[:, :2]
    normal = np.array([-np.sin(np.radians(angle_deg)), np.cos(np.radians(angle_deg))])
    distance = (centres - [W / 2, H / 2]) @ normal
    shape = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 0.0]])
    history = _history(400.0, 1000.0)
    strain, datasets = np.zeros((len(quads), 3, 3)), []
    for k in range(STEPS + 1):
        if k > 2:  # after the peak: the band of the window this step falls in
            fwhm = 1e-3 * thickness_mm[min((k - 3) // 5, len(thickness_mm) - 1)]
            rate = 0.2 + np.exp(-0.5 * (distance / (fwhm / 2.3548)) ** 2)
            strain += 1e-3 * rate[:, None, None] * shape
        name = f"biaxial_{k:04d}.vtu"
        meshio.write(folder / name, meshio.Mesh(points, [("quad", quads)],
                                                cell_data={"strain": [strain.reshape(-1, 9)]}))
        datasets.append(f'<DataSet timestep="{history["load_factor"][k]:.10g}" file="{name}"/>')
    (folder / "biaxial.pvd").write_text('<?xml version="1.0"?><VTKFile type="Collection"><Collection>'
                                        + "".join(datasets) + "</Collection></VTKFile>")
    history.write_csv(folder / "history.csv")
    return folder, h


def test_the_band_is_compared_with_the_finest_mesh_window_by_window(tmp_path):
    """On 48 elements across (h = 1.04 mm) the band is 6 mm thick in all four windows; on 36 6.5 mm; on 24
    6.5 mm in the first window and 9 mm after it. The two coarser meshes are within one element of the
    finest in the first window, and only the 36-element mesh after it."""
    runs = [_run_folder(tmp_path / f"r{n}", n, t) for n, t in
            ((24, (6.5, 9.0, 9.0)), (48, (6.0, 6.0, 6.0)), (36, (6.5, 6.5, 6.5)))]
    table = band_spread([f for f, _ in runs], [h for _, h in runs])
    assert table.metadata["windows"] == 4 and table.metadata["arm"] == "rising"
    assert table.metadata["finest_element_size_mm"] == pytest.approx(50.0 / 48)
    rows = {(int(r["window"]), round(r["element_size_mm"], 2)): r for r in table.rows()}
    assert len(rows) == 8
    for w in (1, 2, 3, 4):
        assert rows[w, 1.39]["finest_thickness_mm"] == pytest.approx(6.0, rel=0.05)
        assert rows[w, 1.39]["finest_angle_deg"] == pytest.approx(60.0, abs=1.0)
        assert rows[w, 1.39]["difference_mm"] == pytest.approx(0.5, abs=0.1) and rows[w, 1.39]["within_one_element"]
    assert rows[1, 2.08]["difference_mm"] == pytest.approx(0.5, abs=0.1) and rows[1, 2.08]["within_one_element"]
    for w in (2, 3, 4):
        assert rows[w, 2.08]["difference_mm"] == pytest.approx(3.0, abs=0.1) and not rows[w, 2.08]["within_one_element"]
    said = describe(band=table)
    assert said.startswith("the rising band within one element of the finest mesh (1.04 mm) in 1 of 4 windows")
    assert "first miss: window 2" in said
    with pytest.raises(ValueError, match="at least two runs"):
        band_spread([runs[0][0]], [runs[0][1]])
    with pytest.raises(ValueError, match="each must be > 0"):
        band_spread([runs[0][0], runs[1][0]], [runs[0][1], 0.0])
