"""Write the meshes of the femgran cases as files (VTU, readable by meshio and ParaView).

    python meshes/make_meshes.py                 # the default (coarse) set into meshes/
    python meshes/make_meshes.py --refine 2      # twice as fine in every direction

* ``triaxial_hex_<n>.vtu``: the 50 x 50 x 100 mm specimen, n x n x 2n hexahedra (x, y in [0, 0.05] m,
  z in [0, 0.1] m) -- ``femgran triaxial --mesh ...``;
* ``triaxial_tet_<n>.vtu``: the same box in tetrahedra;
* ``footing_quad_<n>.vtu``: the strip-footing domain for B = 1 m (surface y = 0, footing |x| <= 0.5,
  n elements across the half-width, graded outwards) -- ``femgran footing --mesh ...``;
* ``footing_tri_<n>.vtu``: the same in triangles.

The cases build these meshes themselves when no file is given; the files are for users who want to
inspect or edit them (any mesh meshio reads is accepted).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from skfem.io.meshio import to_meshio

from femgran.cases.footing import footing_mesh
from femgran.mesh import box


def main(argv=None) -> list[Path]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--refine", type=int, default=1, help="refinement factor (1: the coarse default set)")
    ap.add_argument("--out", default=str(Path(__file__).parent), help="output folder")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    r = int(args.refine)
    if r < 1:
        raise ValueError(f"--refine {r}: must be >= 1")
    written = []
    n = 4 * r
    for kind in ("hex", "tet"):
        m = box(0.05, 0.05, 0.1, n, n, 2 * n, kind=kind)
        written.append(out / f"triaxial_{kind}_{n}.vtu")
        to_meshio(m, encode_cell_data=False).write(written[-1])
    n = 3 * r
    for kind in ("quad", "tri"):
        m = footing_mesh(1.0, resolution=n, kind=kind)
        written.append(out / f"footing_{kind}_{n}.vtu")
        to_meshio(m, encode_cell_data=False).write(written[-1])
    for p in written:
        print(p)
    return written


if __name__ == "__main__":
    main()
