#!/usr/bin/env python3
"""Render one frame of a drape HDF5 file as a shaded 3D surface (PNG).

    render.py out/hang.h5                    # last frame -> out/hang.png
    render.py out/hang.h5 --frame 0 -o first.png

The cloth lattice is drawn with mplot3d's plot_surface, coloured by height and
lit from above, on equally scaled axes. Bad input (missing or non-drape file,
frame out of range) gives a one-line error and exit status 2.
"""

import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LightSource, Normalize  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import drape_h5  # noqa: E402

MAX_FACETS = 128  # facets per lattice direction (larger lattices are subsampled)


def equal_aspect(ax, pts):
    """Same scale on x, y and z: limits hug the data, box aspect = data extents."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.03 * max(hi - lo) + 1e-9
    span = np.maximum(hi - lo, 0.08 * max(hi - lo)) + 2 * pad  # a flat sheet keeps some depth
    mid = 0.5 * (lo + hi)
    ax.set_xlim(mid[0] - span[0] / 2, mid[0] + span[0] / 2)
    ax.set_ylim(mid[1] - span[1] / 2, mid[1] + span[1] / 2)
    ax.set_zlim(mid[2] - span[2] / 2, mid[2] + span[2] / 2)
    ax.set_box_aspect(span)


def render(run, frame, out, dpi=150):
    """Draw frame `frame` (a valid non-negative index) of `run` to the file `out`."""
    p = run.positions[frame]  # [My, Mx, 3]
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    colours = plt.get_cmap("viridis")(Normalize(z.min(), z.max() + 1e-12)(z))

    fig = plt.figure(figsize=(7, 6.5))
    ax = fig.add_subplot(projection="3d")
    ax.plot_surface(x, y, z, facecolors=colours, shade=True, lightsource=LightSource(azdeg=315, altdeg=50),
                    rcount=min(z.shape[0], MAX_FACETS), ccount=min(z.shape[1], MAX_FACETS),
                    linewidth=0, antialiased=False)
    equal_aspect(ax, p.reshape(-1, 3))
    ax.view_init(elev=20, azim=-60)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")

    my, mx = z.shape
    ax.set_title(f"drape: t = {run.time[frame]:.4g} s (frame {frame} of 0..{run.nframes - 1}, step {run.step[frame]})\n"
                 f"{mx} x {my} particles")
    if "kinetic" in run.energies:
        fig.text(0.02, 0.02, f"kinetic energy {run.energies['kinetic'][frame]:.4g} J", fontsize=9)
    fig.text(0.98, 0.02, os.path.basename(run.path), fontsize=8, ha="right", color="0.4")

    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    fig.savefig(out, dpi=dpi, bbox_inches="tight")
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("file", help="drape HDF5 output (-output_file)")
    ap.add_argument("-o", "--output", help="PNG to write (default: FILE with .png)")
    ap.add_argument("--frame", type=int, default=-1, help="frame index, negative counts from the end (default -1: last)")
    ap.add_argument("--dpi", type=int, default=150, help="resolution of the PNG (default 150)")
    args = ap.parse_args(argv)

    try:
        run = drape_h5.load(args.file)
    except ValueError as e:
        ap.error(str(e))  # exit status 2
    n = run.nframes
    if n == 0:
        ap.error(f"{args.file}: no complete frame")
    if not -n <= args.frame < n:
        ap.error(f"--frame {args.frame} out of range: {args.file} has {n} frame(s) (valid {-n}..{n - 1})")
    out = args.output or os.path.splitext(args.file)[0] + ".png"
    render(run, args.frame % n, out, dpi=args.dpi)
    print(f"render: wrote {out} (frame {args.frame % n}, t = {run.time[args.frame]:.4g} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
