"""The DEM example runs and the command line works end to end (small sizes)."""

import runpy
from pathlib import Path

import numpy as np
import pytest

import dem.cli
from material import load_parameters


def femgran_main(argv):
    """``femgran`` with only the DEM subcommands (independent of the other areas' parsers), with the
    same bad-input handling as femgran.cli.main: one line on stderr and exit code 2."""
    import argparse
    import sys

    parser = argparse.ArgumentParser(prog="femgran")
    dem.cli.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, KeyError, FileNotFoundError) as exc:
        print(f"femgran {args.command}: error: {exc}", file=sys.stderr)
        return 2

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_example_dem_01_calibrates_a_readable_parameter_file(tmp_path):
    mod = runpy.run_path(str(EXAMPLES / "dem_01_biaxial_rotation.py"))
    res = mod["main"](out=tmp_path, n=150, axial_strain=0.02, rotation_deg=30.0)
    assert 15.0 < res["phi_peak_deg"] < 40.0
    params = load_parameters(res["parameters"])
    assert params.beta == pytest.approx(res["beta"])
    assert 0.0 <= params.beta < 2.0
    assert params.beta_hat == 0.0 and params.alpha_hat > 0.0  # 2D: beta_hat not identifiable


def test_cli_generate_biaxial_fabric_calibrate(tmp_path, capsys):
    sample = tmp_path / "s.npz"
    assert femgran_main(["dem", "generate", "--n", "120", "--out", str(sample)]) == 0
    assert femgran_main(["dem", "biaxial", str(sample), "--axial-strain", "0.01", "--records", "6",
                         "--out", str(tmp_path / "b")]) == 0
    assert femgran_main(["dem", "fabric", str(tmp_path / "b"), "--measure", "mil", "--spacing-um", "10",
                         "--out", str(tmp_path / "f.csv")]) == 0
    assert femgran_main(["calibrate", str(tmp_path / "b"), "--out", str(tmp_path / "p.toml")]) == 0
    assert load_parameters(tmp_path / "p.toml").beta >= 0.0
    out = capsys.readouterr().out
    assert "wall stress [-100. -100.] kPa" in out
    # bad input: one clear line and exit code 2
    assert femgran_main(["dem", "biaxial", str(tmp_path / "missing.npz")]) == 2
    assert "does not exist" in capsys.readouterr().err
