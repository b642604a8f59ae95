"""Read the HDF5 frames written by drape (``-output_file F.h5``).

Usage::

    import drape_h5
    run = drape_h5.load("out/hang.h5")
    run.positions[-1]          # last frame, shape [My, Mx, 3], index [j][i][xyz]
    run.energies["kinetic"]    # shape [nframes]

Only complete frames are returned: drape writes ``/time`` last in each frame,
so a run killed mid-frame may leave the other datasets one frame longer.
"""

from dataclasses import dataclass, field
import os

import h5py
import numpy as np

ENERGIES = ("kinetic", "gravity", "stretch", "shear", "bend")
_REQUIRED = ("position", "velocity", "time", "step")


@dataclass
class DrapeRun:
    """The frames of one drape run (arrays cover complete frames only)."""

    path: str
    positions: np.ndarray  # [nframes, My, Mx, 3] (m)
    velocities: np.ndarray  # [nframes, My, Mx, 3] (m/s)
    time: np.ndarray  # [nframes] (s)
    step: np.ndarray  # [nframes] time-step number of each frame
    energies: dict = field(default_factory=dict)  # name -> [nframes] (J)
    attrs: dict = field(default_factory=dict)  # root attributes, str decoded

    @property
    def nframes(self):
        """Number of complete frames."""
        return len(self.time)

    def __getitem__(self, key):
        """Dict-style access: run["positions"] is run.positions."""
        return getattr(self, key)

    def total_energy(self):
        """Sum of the energies present, per frame."""
        return sum(self.energies.values(), np.zeros(self.nframes))


def _decode(value):
    """HDF5 attribute -> plain Python value (bytes to str, 0-d arrays to scalars)."""
    if isinstance(value, (bytes, np.bytes_)):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "S":
            return [v.decode("utf-8", "replace") for v in value.ravel()]
        return value.item() if value.size == 1 else value
    if isinstance(value, np.generic):
        return value.item()
    return value


def load(path):
    """Load a drape HDF5 file; raise ValueError if it is missing or not drape's."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise ValueError(f"{path}: not an HDF5 file ({e})") from None
    with f:
        if "time" not in f:
            raise ValueError(f"{path}: no /time dataset (not a drape output file, or no frame written)")
        missing = [name for name in _REQUIRED if name not in f]
        if missing or "drape_version" not in f.attrs:
            what = f"missing /{', /'.join(missing)}" if missing else "no drape_version attribute"
            raise ValueError(f"{path}: not a drape output file ({what})")
        n = f["time"].shape[0]
        pos = f["position"]
        if pos.ndim != 4 or pos.shape[3] != 3 or pos.shape[0] < n:
            raise ValueError(f"{path}: /position has shape {pos.shape}, expected [>={n}][My][Mx][3]")
        return DrapeRun(
            path=path,
            positions=pos[:n],
            velocities=f["velocity"][:n],
            time=f["time"][:n].reshape(n),
            step=f["step"][:n].reshape(n).astype(np.int64),
            energies={e: f[f"energy_{e}"][:n].reshape(n) for e in ENERGIES if f"energy_{e}" in f},
            attrs={k: _decode(v) for k, v in f.attrs.items()},
        )
