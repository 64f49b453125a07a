"""The shipped tree is self-contained: no absolute paths of a build machine, no citations of documents
the repository does not ship (the package's own documentation is under ``docs/``)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("femgran", "material", "dem", "benchmarks", "examples", "meshes", "tests", "docs", "README.md")
SKIPPED_DIRS = {"__pycache__", ".pytest_cache"}
BINARY_SUFFIXES = {".npz", ".npy", ".png", ".pyc", ".pkl"}

# an absolute path under the work, tmp or home folder of a machine; the slash must not follow a name
# character, so URLs (https://host/org/work/...) and relative paths (out/tmp/...) do not count
ABSOLUTE_PATH = re.compile(r"(?<![\w.~-])/(?:work|tmp|home)/")
# specification documents that live outside the repository
UNSHIPPED = re.compile(r"\b(?:MODEL|API|CASES|STYLE|ROBUSTNESS)\.md\b")


def _files():
    for name in SCANNED:
        top = ROOT / name
        if top.is_file():
            yield top
            continue
        for path in sorted(top.rglob("*")):
            if path.is_file() and not SKIPPED_DIRS & set(path.relative_to(ROOT).parts):
                if path.suffix.lower() not in BINARY_SUFFIXES:
                    yield path


def _hits(pattern: re.Pattern, exclude: tuple[Path, ...] = ()) -> list[str]:
    hits = []
    for path in _files():
        if path in exclude:
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        for lineno, line in enumerate(text.splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{lineno}: {line.strip()[:120]}")
    return hits


def test_the_scanned_tree_exists():
    missing = [name for name in SCANNED if not (ROOT / name).exists()]
    assert not missing, f"expected in the repository: {missing}"


@pytest.mark.parametrize("line, found", [
    ('BENCH_DIR = Path("{s}work{s}shared{s}bench")', True),
    ("see ``{s}home{s}user{s}x.md``", True),
    ("written to {s}tmp{s}run", True),
    ("https://github.com{s}org{s}work{s}tree", False),
    ("out{s}tmp{s}run", False),
])
def test_absolute_path_pattern(line, found):
    # the samples are assembled here so that this file itself holds no absolute path
    assert bool(ABSOLUTE_PATH.search(line.format(s="/"))) is found


def test_no_absolute_machine_paths():
    hits = _hits(ABSOLUTE_PATH)
    assert not hits, "absolute paths of a machine (pass them as arguments instead):\n" + "\n".join(hits)


def test_no_citations_of_documents_the_repository_does_not_ship():
    hits = _hits(UNSHIPPED, exclude=(Path(__file__).resolve(),))
    assert not hits, "citations of documents outside the repository (cite docs/ instead):\n" + "\n".join(hits)
