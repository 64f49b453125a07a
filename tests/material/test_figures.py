"""`femgran figures`: the material figures are written with their data, and the data carry the trends."""

import csv

import numpy as np

from femgran.cli import main


def _read(path):
    with open(path) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    head = rows[0]
    cols = {h: [] for h in head}
    for r in rows[1:]:
        for h, v in zip(head, r):
            if v != "":
                cols[h].append(float(v))
    return {h: np.array(v) for h, v in cols.items()}


def test_figures_cli_writes_png_and_csv(tmp_path):
    assert main(["figures", "--out", str(tmp_path), "--only", "fig14", "fig45", "--no-progress"]) == 0
    for stem in ("fig14_friction_distribution", "fig45_rotation_beta"):
        assert (tmp_path / f"{stem}.png").stat().st_size > 10_000
        assert (tmp_path / f"{stem}.csv").is_file()
    assert (tmp_path / "run.json").is_file()
    f14 = _read(tmp_path / "fig14_friction_distribution.csv")
    # eta_f(alpha) rises from the vertical to the horizontal direction, like the Fig. 8 slopes
    assert f14["eta_f_order4"][-1] > f14["eta_f_order4"][0] + 0.2
    f45 = _read(tmp_path / "fig45_rotation_beta.csv")
    # strength gap between dpsi = 0 and 90 at the end of the reshear grows with beta (Fig. 45)
    gaps = [f45[f"q_kPa_b{b}_psi0"][-1] - f45[f"q_kPa_b{b}_psi90"][-1] for b in ("0.1", "5", "10")]
    assert gaps[0] < gaps[1] < gaps[2]


def test_unknown_figure_is_rejected(capsys, tmp_path):
    assert main(["figures", "--only", "fig99", "--out", str(tmp_path)]) == 2
    assert "figures --only ['fig99']: allowed the groups" in capsys.readouterr().err
