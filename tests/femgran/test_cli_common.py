"""Every subcommand speaks the same flags (material.commandline): --out, --no-progress, --params/--set, run.json."""

import json

import pytest

from femgran.cli import build_parser, main
from material import load_parameters
from material.commandline import parse_set

# every subcommand that writes something, with the positional arguments it needs
COMMANDS = [["element", "triaxial"], ["element", "path", "x.csv"], ["triaxial"], ["footing"], ["biaxial"],
            ["run", "case.toml"], ["figures"], ["dem", "generate"], ["dem", "biaxial", "s.npz"],
            ["dem", "rotate", "s.npz"], ["dem", "sweep"]]


@pytest.mark.parametrize("command", COMMANDS, ids=" ".join)
def test_every_subcommand_has_progress_on_a_terminal_by_default_and_both_flags(command):
    parser = build_parser()
    assert parser.parse_args(command).progress is None  # (resolved by main: on a terminal only)
    assert parser.parse_args(command + ["--no-progress"]).progress is False
    assert parser.parse_args(command + ["--progress"]).progress is True
    if command[0] != "run":
        assert str(parser.parse_args(command + ["--out", "somewhere"]).out) == "somewhere"


def test_the_progress_bar_is_drawn_on_a_terminal_unless_asked_for(tmp_path, capsys, monkeypatch):
    """Where stderr is a file or a pipe (a batch job's log) the command line draws no bar unless --progress
    asks for it: the bar's carriage-return updates made the log of ``femgran footing --alpha 0`` one line of
    20 kB. On a terminal it is drawn, and --no-progress silences it there."""
    import io

    run = ["biaxial", "--resolution", "2", "--steps", "3", "--out"]
    assert main(run + [str(tmp_path / "log")]) == 0
    assert "%|" not in capsys.readouterr().err
    assert main(run + [str(tmp_path / "asked"), "--progress"]) == 0
    assert "t=1.000/1.000" in capsys.readouterr().err

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    screen = Terminal()
    monkeypatch.setattr("sys.stderr", screen)
    assert main(run + [str(tmp_path / "screen")]) == 0
    assert "%|" in screen.getvalue() and "t=1.000/1.000" in screen.getvalue()
    quiet = Terminal()
    monkeypatch.setattr("sys.stderr", quiet)
    assert main(run + [str(tmp_path / "quiet"), "--no-progress"]) == 0
    assert "%|" not in quiet.getvalue()


@pytest.mark.parametrize("command", [["element", "triaxial"], ["footing"], ["triaxial"], ["biaxial"]], ids=" ".join)
def test_the_material_flags_are_the_same_everywhere(command):
    parser = build_parser()
    for flag in ("--params", "--parameters"):
        args = parser.parse_args(command + [flag, "sand.toml", "--set", "beta=5", "--set", "a=0.4,0.45,19"])
        assert args.params == "sand.toml"
        assert parse_set(args.set) == {"beta": 5.0, "a": [0.4, 0.45, 19.0]}


def test_set_with_lists_reaches_the_parameters(tmp_path):
    out = tmp_path / "el"
    assert main(["element", "triaxial", "--alpha", "0", "--steps", "5", "--set", "a=0.4,0.45,19", "--set", "b=0.1",
                 "--no-progress", "--no-plot", "--out", str(out)]) == 0
    params = load_parameters(out / "parameters.toml")
    assert params.a == (0.4, 0.45, 19.0) and params.b == (0.1,)
    assert main(["element", "triaxial", "--set", "beta=five", "--out", str(out)]) == 2


def test_run_json_records_the_command_and_the_options(tmp_path):
    argv = ["footing", "--law", "drucker_prager", "--friction", "30", "--resolution", "1", "--steps", "2",
            "--settlement", "0.005", "--no-progress", "--out", str(tmp_path)]
    assert main(argv) == 0
    record = json.loads((tmp_path / "run.json").read_text())
    assert record["command"] == "femgran " + " ".join(argv)
    assert record["options"]["law"] == "drucker_prager" and record["options"]["progress"] is False
    assert record["runs"][0]["completed"] is True and "femgran_version" in record


def test_the_rule_flag_chooses_the_planes_of_the_cpa_law(capsys):
    """--rule reaches the case's CPA law (default: the thesis's 33 planes); an unknown rule is refused with
    the list of rules."""
    from femgran.cases import Footing
    from femgran.cases.base import build_problem
    from femgran.cases.cli import _material

    parser = build_parser()
    case = Footing(resolution=1)
    for flags, planes in (([], 33), (["--rule", "equator-78"], 78), (["--rule", "lebedev-26"], 13)):
        assert build_problem(case, _material(parser.parse_args(["footing", *flags]))).material.n_planes == planes
    with pytest.raises(SystemExit):
        parser.parse_args(["footing", "--rule", "bazant-oh-34"])
    err = capsys.readouterr().err
    assert "invalid choice: 'bazant-oh-34'" in err and "equator-78" in err


def test_the_stabilisation_flag_takes_a_number_or_minimal(capsys):
    """--stabilisation reaches the case's CPA law as a number or "minimal" (docs/cpa_law.md section 4); the
    default is the thesis's law; anything else is refused with the allowed values."""
    from femgran.cases import Footing
    from femgran.cases.base import build_problem
    from femgran.cases.cli import _material

    parser = build_parser()
    case = Footing(resolution=1)
    for flags, expected in (([], 0.0), (["--stabilisation", "minimal"], "minimal"), (["--stabilisation", "0.1"], 0.1)):
        spec = _material(parser.parse_args(["footing", *flags]))
        assert build_problem(case, spec).material.options.stabilisation == expected, flags
    with pytest.raises(SystemExit):
        parser.parse_args(["footing", "--stabilisation", "maximal"])
    assert "'maximal': allowed a number 0 <= MU <= 1 or 'minimal'" in capsys.readouterr().err
    # --relaxation-time: the stabilisation's own relaxation time reaches the law; without a stabilisation the
    # law refuses it, naming the key
    spec = _material(parser.parse_args(["footing", "--stabilisation", "0.1", "--relaxation-time", "0.025"]))
    assert spec["relaxation_time"] == 0.025 and build_problem(case, spec).material.relaxation_time == 0.025
    assert "relaxation_time" not in _material(parser.parse_args(["footing", "--stabilisation", "0.1"]))
    with pytest.raises(ValueError, match="relaxation_time = 0.025: the relaxation time of the step stabilisation"):
        build_problem(case, _material(parser.parse_args(["footing", "--relaxation-time", "0.025"])))
