"""The packages' boundaries: ``material`` and ``dem`` stand without the FE package."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("package", ["material", "dem"])
def test_material_and_dem_never_import_femgran(package):
    pattern = re.compile(r"^\s*(from\s+femgran[\s.]|import\s+femgran\b)", re.MULTILINE)
    offenders = [p.relative_to(ROOT).as_posix() for p in sorted((ROOT / package).rglob("*.py"))
                 if pattern.search(p.read_text())]
    assert offenders == []


@pytest.mark.parametrize("statement, absent", [
    ("import material", ("femgran", "skfem", "dem")),
    ("import dem", ("femgran", "skfem")),
    ("import femgran", ("skfem", "femgran.cases", "femgran.solver")),
])
def test_importing_a_package_loads_only_what_it_needs(statement, absent):
    code = f"import sys; {statement}; print(','.join(m for m in {absent!r} if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                            cwd=ROOT).stdout.strip()
    assert loaded == ""


def test_every_package_reports_the_distribution_version():
    from importlib.metadata import version

    import dem.experiments
    import femgran
    import material.version

    assert femgran.__version__ == material.version.__version__ == dem.experiments._version() == version("femgran")
