#!/usr/bin/env python3
"""Animate the frames of a drape HDF5 file (GIF, or MP4 when ffmpeg is installed).

    animate.py out/sphere.h5 -o sphere.gif               # every frame
    animate.py out/sphere.h5 -o sphere.gif --every 3 --fps 12
    animate.py out/sphere.h5 -o sphere.gif --tmax 0.8     # the frames up to t = 0.8 s
    animate.py out/sphere.h5 -o sphere.mp4               # needs ffmpeg on PATH

Each picture is drawn as render.py draws one frame (cloth, solid, floor) on axes
that stay fixed over the run. The frames shown are 0, N, 2N, ... (--every N) and
always the last one (of those up to --tmax). Bad input gives a one-line error
and exit status 2.
"""

import argparse
import os
import shutil
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.animation import FFMpegWriter, PillowWriter  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import render  # noqa: E402

FORMATS = {".gif": "GIF (Pillow)", ".mp4": "MP4 (ffmpeg)"}


class GifWriter(PillowWriter):
    """matplotlib's PillowWriter with one palette shared by all pictures and no
    dithering: smooth shading then neither speckles nor flickers from frame to frame."""

    def finish(self):
        from PIL import Image

        frames = getattr(self, "_frames", None)
        if not frames:
            return super().finish()
        rgb = [f.convert("RGB") for f in frames]
        sample = rgb[:: max(1, len(rgb) // 12)]  # the palette is made from a dozen pictures
        w, h = rgb[0].size
        mosaic = Image.new("RGB", (w, h * len(sample)))
        for k, im in enumerate(sample):
            mosaic.paste(im, (0, h * k))
        palette = mosaic.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        pics = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in rgb]
        pics[0].save(self.outfile, save_all=True, append_images=pics[1:], duration=int(round(1000 / self.fps)),
                     loop=0, optimize=False)


def frames_shown(nframes, every, count=None):
    """Indices of the frames an animation shows: 0, every, 2 every, ... and the last
    (of the first `count` frames, if given)."""
    nframes = nframes if count is None else min(nframes, count)
    frames = list(range(0, nframes, every))
    if frames[-1] != nframes - 1:
        frames.append(nframes - 1)
    return frames


def animate(run, out, every=1, fps=15, dpi=80, elev=render.ELEV, azim=render.AZIM, width=6.0, tmax=None, log=None):
    """Write the animation of `run` to `out` (.gif or .mp4); returns the frames shown."""
    count = None if tmax is None else max(1, int((run.time <= tmax * (1 + 1e-12)).sum()))
    frames = frames_shown(run.nframes, every, count)
    scene = render.Scene(run, frames, elev=elev, azim=azim)
    fig, ax = scene.figure(width=width)
    if os.path.splitext(out)[1].lower() == ".mp4":
        writer = FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
    else:
        writer = GifWriter(fps=fps)
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    try:
        with writer.saving(fig, out, dpi):
            for n, k in enumerate(frames):
                scene.draw(fig, ax, k)
                writer.grab_frame()
                if log:
                    log(f"\ranimate: frame {n + 1}/{len(frames)}")
    finally:
        plt.close(fig)
    if log:
        log("\n")
    return frames


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("file", help="drape HDF5 output (-output_file)")
    ap.add_argument("-o", "--output", help="animation to write, .gif or .mp4 (default: FILE with .gif)")
    ap.add_argument("--every", type=int, default=1, help="show every N-th frame (default 1: all; the last is always shown)")
    ap.add_argument("--tmax", type=float, help="only the frames up to this time, s (default: all)")
    ap.add_argument("--fps", type=float, default=15, help="pictures per second (default 15)")
    ap.add_argument("--dpi", type=int, default=80, help="resolution (default 80: 480 x 424 pixels)")
    ap.add_argument("--elev", type=float, default=render.ELEV, help=f"view elevation, degrees (default {render.ELEV:g})")
    ap.add_argument("--azim", type=float, default=render.AZIM, help=f"view azimuth, degrees (default {render.AZIM:g})")
    args = ap.parse_args(argv)

    out = args.output or os.path.splitext(args.file)[0] + ".gif"
    ext = os.path.splitext(out)[1].lower()
    if ext not in FORMATS:
        ap.error(f"{out}: unknown animation format {ext or '(none)'}; use .gif or .mp4")
    if ext == ".mp4" and shutil.which("ffmpeg") is None:
        ap.error(f"{out}: MP4 needs ffmpeg, which is not on PATH (install it, e.g. apt-get install ffmpeg, or write a .gif)")
    if args.every < 1:
        ap.error(f"--every must be at least 1; got {args.every}")
    if not args.fps > 0:
        ap.error(f"--fps must be positive; got {args.fps:g}")
    if args.dpi <= 0:
        ap.error(f"--dpi must be positive; got {args.dpi}")
    run = render.load_or_exit(ap, args.file)

    progress = sys.stderr.write if sys.stderr.isatty() else None
    try:
        frames = animate(run, out, every=args.every, fps=args.fps, dpi=args.dpi, elev=args.elev, azim=args.azim,
                         tmax=args.tmax, log=progress)
    except OSError as e:
        ap.error(f"cannot write {out}: {e.strerror or e}")
    print(f"animate: wrote {out} ({len(frames)} frames of {run.nframes}, t = {run.time[frames[0]]:.4g}..{run.time[frames[-1]]:.4g} s, "
          f"{os.path.getsize(out) / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
