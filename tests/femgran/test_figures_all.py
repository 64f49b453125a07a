"""``femgran figures``: every figure from the package's own runs, each PNG with its CSV, an index of them."""

import re

import numpy as np
import pytest

from femgran.cli import main
from femgran.figures import make_all
from material.sweep import read_summary
from material.table import read_table


def _check_index(out, drawn):
    """Every PNG written is in the index with a sentence, every entry exists, every PNG has its CSV."""
    index = (out / "README.md").read_text()
    listed = re.findall(r"^- \[([^\]]+\.png)\]\(\1\)(?: \(\[data\]\(([^)]+)\)\))?: (.+)$", index, re.M)
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert sorted(name for name, _, _ in listed) == pngs == sorted(f"{s}.png" for s in drawn)
    for name, csv, sentence in listed:
        assert csv == name.replace(".png", ".csv") and (out / csv).is_file()
        assert len(sentence) > 30, f"{name}: no sentence on what it shows"


def test_the_index_lists_every_figure_written(tmp_path):
    out = tmp_path / "figs"
    drawn = make_all(out, only=["fig14", "envelope"], progress=False, scheduler="serial")
    assert sorted(drawn) == ["fig14_friction_distribution", "strength_envelope"]
    _check_index(out, drawn)
    data = read_table(out / "fig14_friction_distribution.csv")
    assert len(data["alpha_deg"]) == 91
    # a second call finds both runs complete: nothing runs again, the index is the same
    again = make_all(out, only=["fig14", "envelope"], progress=False, scheduler="serial")
    assert again == drawn and list(read_summary(out / "runs")["completed"]) == [1, 1]


def test_unknown_figure_names_are_named(tmp_path, capsys):
    assert main(["figures", "--only", "fig99", "--out", str(tmp_path)]) == 2
    assert "fig99" in capsys.readouterr().err


@pytest.mark.slow
def test_the_reduced_figure_set(tmp_path):
    """The whole set at the reduced size (about 4 minutes on two cores), with the trends the thesis states."""
    out = tmp_path / "all"
    assert main(["figures", "--out", str(out), "--no-progress"]) == 0
    drawn = {p.stem: "" for p in out.glob("*.png")}
    _check_index(out, drawn)
    expected = ["fig14", "fig20", "fig21", "fig45", "fig46", "fig47", "strength_envelope",  # model
                "fig23", "fig24", "fig25", "fig26", "fig27", "fig28", "fig38", "fig39", "fig40", "fig41", "fig42",
                "fig43", "fig44",  # DEM
                "bearing_capacity_vs_alpha", "bearing_mechanisms", "triaxial_nonuniformity_vs_alpha",
                "shear_band_meshes", "shear_band_fields", "shear_band_vs_alpha"]
    for stem in expected:
        assert any(s.startswith(stem) for s in drawn), f"{stem} missing"
    runs = read_summary(out / "runs")
    keys = runs.metadata["runs"]
    cap = {a: c for k, a, c in zip(keys, runs["alpha_deg"], runs["bearing_capacity_kPa"]) if k.startswith("footing")}
    # bedding along the load (alpha 90) carries less than bedding across it
    assert cap[90.0] < 0.95 * cap[0.0]
    ratio = [r for k, r in zip(keys, runs["final_q_over_element"]) if k.startswith("triaxial")]
    assert all(r > 1.0 for r in ratio)  # rough platens confine the specimen's ends
    # the softening specimens localise: each in a band at 45-75 deg, on the finer two meshes in its main arm; on
    # the coarsest (4 elements across) the main arm's peak, about three elements wide, exceeds half the section and the
    # detector calls it a zone (femgran.band.is_zone), so there the band is the conjugate arm
    biaxial = [i for i, k in enumerate(keys) if k.startswith("biaxial")]
    assert len(biaxial) == 3

    def band(i, prefix=""):
        return runs[prefix + "localised"][i] == 1 and 45.0 < runs[prefix + "band_angle_deg"][i] < 75.0

    coarsest = min(runs["resolution"][i] for i in biaxial)
    assert all(band(i) or band(i, "conjugate_") for i in biaxial)
    assert all(band(i) for i in biaxial if runs["resolution"][i] > coarsest)
