"""femgran.output: parameters, history plots, the written series and the off-screen field plots."""

import ctypes.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import material
from femgran import __version__, output
from femgran.cases import footing
from femgran.output import plot_field, plot_history, read_pvd, write_parameters
from femgran.solver import History


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """An elastic footing on the coarsest mesh (< 1 s): 4 history rows, fields written every 2nd step."""
    out = tmp_path_factory.mktemp("footing")
    sol = footing(material.LinearElastic(2e4, 0.3), settlement_m=0.01, steps=3, resolution=1, out=out, plots=False,
                  write_every=2)
    return sol, out


def _colours(png, window=(slice(None), slice(None))):
    import matplotlib.image

    img = matplotlib.image.imread(png)[window]
    return len(np.unique(img.reshape(-1, img.shape[-1]), axis=0))


def test_series_written_every_second_step_and_the_last_on_close(run):
    sol, out = run
    entries = read_pvd(out / "footing.pvd")
    lam = sol.history["load_factor"]
    assert len(lam) == 4
    np.testing.assert_allclose([t for t, _ in entries], [lam[0], lam[2], lam[3]], atol=1e-9)
    assert [f.name for _, f in entries] == [f"footing_{i:04d}.vtu" for i in range(3)]
    assert all(f.is_file() and f.parent == out for _, f in entries)
    hist = History.read_csv(out / "history.csv")
    assert len(hist) == 4
    np.testing.assert_array_equal(hist["load_factor"], lam)  # 17 digits: read back to the bit
    assert json.loads((out / "status.json").read_text())["completed"] is True
    assert not list(out.glob(".*.tmp"))  # the atomic rewrite leaves no temporary file


def test_write_parameters_round_trip(tmp_path):
    params = {"E": np.float64(2e4), "n": np.int64(3), "axes": np.eye(2), "mesh": Path("a/b.vtu"),
              "nested": {"flag": True, "name": "x"}, "law": object}
    path = write_parameters(tmp_path / "p.json", params)
    data = json.loads(path.read_text())
    assert data.pop("femgran_version") == __version__
    assert data == {"E": 2e4, "n": 3, "axes": [[1.0, 0.0], [0.0, 1.0]], "mesh": str(Path("a/b.vtu")),
                    "nested": {"flag": True, "name": "x"}, "law": repr(object)}


def test_plot_history_with_references(tmp_path):
    h = {"x": np.linspace(0, 1, 5), "y": np.linspace(0, 2, 5)}
    for ref in (None, ("ref", [0, 1], [0, 1]), [("a", [0, 1], [0, 2]), ("b", [0, 1], [1, 1])]):
        p = plot_history(h, "x", "y", tmp_path / "h.png", title="t", reference=ref)
        assert p == tmp_path / "h.png" and _colours(p) > 10


_CHILD = """
import sys
from femgran.output import plot_field
print(plot_field(sys.argv[1], "displacement", sys.argv[2], component="norm", warp=5.0))
"""


@pytest.mark.parametrize("env", [{}, {"DISPLAY": ":99", "PYVISTA_OFF_SCREEN": "true"}],
                         ids=["headless", "stale-display"])
def test_plot_field_renders_off_screen_without_x_warnings(run, tmp_path, env):
    """No DISPLAY (or a dead one with PYVISTA_OFF_SCREEN=true): VTK renders with EGL/OSMesa directly,
    without first probing X ("bad X server connection"), and the PNG shows the mesh, not a blank."""
    _, out = run
    child_env = {k: v for k, v in os.environ.items()
                 if k not in ("DISPLAY", "PYVISTA_OFF_SCREEN", "VTK_DEFAULT_OPENGL_WINDOW")} | env
    png = tmp_path / "field.png"
    r = subprocess.run([sys.executable, "-c", _CHILD, str(read_pvd(out / "footing.pvd")[-1][1]), str(png)],
                       env=child_env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    if r.stdout.strip() == "None":
        pytest.skip("no headless OpenGL (EGL/OSMesa) on this machine")
    assert r.stdout.strip() == str(png) and png.is_file()
    assert "X server" not in r.stderr and "Warning" not in r.stderr and "WARN" not in r.stderr, r.stderr
    assert _colours(png) > 50
    # the middle of the picture is the (coloured) mesh: a blank render would be uniform there
    assert _colours(png, (slice(250, 350), slice(200, 600))) > 10


@pytest.fixture
def fresh_setup(monkeypatch):
    """_offscreen_pyvista evaluated afresh against a controlled environment, and restored afterwards."""
    import pyvista as pv

    for k in ("DISPLAY", "PYVISTA_OFF_SCREEN", "VTK_DEFAULT_OPENGL_WINDOW"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setattr(pv, "OFF_SCREEN", pv.OFF_SCREEN)
    output._offscreen_pyvista.cache_clear()
    yield monkeypatch
    output._offscreen_pyvista.cache_clear()


LIBC = ("vtkEGLRenderWindow", (ctypes.util.find_library("c") or "libc.so.6",))  # loadable: stands for libEGL
NONE = ("vtkEGLRenderWindow", ("libsurely-missing-egl.so.1",))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the window class is chosen on Linux only")
@pytest.mark.parametrize("env, gl, expect", [
    ({}, (NONE,), None),  # headless and nothing to render with: no plot instead of a VTK crash
    ({}, (LIBC,), "vtkEGLRenderWindow"),
    ({"VTK_DEFAULT_OPENGL_WINDOW": "vtkOSOpenGLRenderWindow"}, (NONE,), "vtkOSOpenGLRenderWindow"),  # user's choice
    ({"DISPLAY": ":0"}, (LIBC,), "unset"),  # a display is left alone ...
    ({"DISPLAY": ":0", "PYVISTA_OFF_SCREEN": "true"}, (LIBC,), "vtkEGLRenderWindow"),  # ... unless off screen is asked
])
def test_offscreen_setup_choices(fresh_setup, env, gl, expect, run, tmp_path):
    for k, v in env.items():
        fresh_setup.setenv(k, v)
    fresh_setup.setattr(output, "_HEADLESS_GL", gl)
    pv = output._offscreen_pyvista()
    assert output._offscreen_pyvista() is pv  # cached
    if expect is None:
        assert pv is None and "VTK_DEFAULT_OPENGL_WINDOW" not in os.environ
        assert plot_field(read_pvd(run[1] / "footing.pvd")[-1][1], "q_kPa", tmp_path / "q.png") is None
        return
    assert pv is not None and os.environ.get("VTK_DEFAULT_OPENGL_WINDOW", "unset") == expect
    if "DISPLAY" not in env:
        assert pv.OFF_SCREEN is True
