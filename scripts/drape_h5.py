"""Read the HDF5 frames written by drape (``-output_file F.h5``).

Usage::

    import drape_h5
    run = drape_h5.load("out/hang.h5")
    run.positions[-1]          # last frame, shape [My, Mx, 3], index [j][i][xyz]
    run.energies["kinetic"]    # shape [nframes]
    run.strain_max             # largest edge strain per frame, shape [nframes]
    run.frame_at(0.5, 1e-9)    # index of the frame at t = 0.5 s, or None
    run.attrs["omega_max"]     # the run's report (and "options"), bytes decoded
    run.active                 # [My, Mx] bool: particles that are part of the cloth
    run.solid_triangles        # [ntri, 3, 3] or None: the solid's mesh (vertex xyz)
    run.floor                  # height of the -solid_floor plane, or None
    run.option("cloth_shape")  # value of an option of the run, or None
    drape_h5.load("big.h5", frames=False)   # the same without the frames' positions and velocities

Only complete frames are returned: drape writes ``/time`` last in each frame,
so a run killed mid-frame may leave the other datasets one frame longer. The file
is opened without HDF5's file locking, so a running drape's frames can be read.
"""

from dataclasses import dataclass, field
import os

import h5py
import numpy as np

ENERGIES = ("kinetic", "gravity", "stretch", "shear", "bend")
CONTACT = ("depth", "count", "force")
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
    attrs: dict = field(default_factory=dict)  # root attributes: options and the run's report, str decoded
    contact: dict = field(default_factory=dict)  # "depth" (m), "count" -> [nframes], "force" (N) -> [nframes, 3], when written
    strain_max: np.ndarray = None  # [nframes] largest stretch of a lattice edge, (l - L)/L, when written
    solid_triangles: np.ndarray = None  # [ntri, 3, 3] (m), or None without a mesh solid
    active: np.ndarray = None  # [My, Mx] bool, True for the particles of the cloth

    def __post_init__(self):
        if self.active is None:
            self.active = active_mask(self.positions.shape[2], self.positions.shape[1], self.option("cloth_shape"))

    @property
    def nframes(self):
        """Number of complete frames."""
        return len(self.time)

    def __getitem__(self, key):
        """Dict-style access: run["positions"] is run.positions."""
        return getattr(self, key)

    @property
    def shape(self):
        """Lattice size (My, Mx)."""
        return self.positions.shape[1:3]

    def option(self, name, default=None):
        """Value (str) of option -name as recorded in the file, "" for a flag, else `default`."""
        return parse_options(self.attrs.get("options", "")).get(name.lstrip("-"), default)

    @property
    def floor(self):
        """Height z of the floor plane (-solid_floor), or None."""
        value = self.option("solid_floor")
        try:
            return float(value) if value else None
        except ValueError:
            return None

    @property
    def active_cells(self):
        """[My-1, Mx-1] bool: lattice cells whose four corners are all active."""
        a = self.active
        return a[:-1, :-1] & a[1:, :-1] & a[:-1, 1:] & a[1:, 1:]

    def total_energy(self):
        """Sum of the energies present, per frame."""
        return sum(self.energies.values(), np.zeros(self.nframes))

    def frame_at(self, t, tol):
        """Index of the first frame within `tol` s of time `t`, or None."""
        k = np.flatnonzero(np.abs(self.time - t) <= tol)
        return int(k[0]) if len(k) else None


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


def parse_options(text):
    """'-a 1 -b -c x' -> {"a": "1", "b": "", "c": "x"} (the last value of an option wins)."""
    opts, key = {}, None
    for tok in str(text).split():
        if tok.startswith("-") and len(tok) > 1 and not _is_number(tok):
            key = tok.lstrip("-")
            opts[key] = ""
        elif key is not None:
            opts[key] = (opts[key] + " " + tok).strip()
    return opts


def _is_number(tok):
    try:
        float(tok.split(",")[0])
        return True
    except ValueError:
        return False


def active_mask(mx, my, shape=None):
    """[My, Mx] bool: the particles of the cloth, for a file without /active. A circle
    specimen (-cloth_shape circle) is the disc inscribed in the lattice, as in drape's
    ClothIsActive (with (i, j) scaled to [-1, 1], a^2 + b^2 <= 1 + 1e-12), less the
    spikes of the cut, as in ClothCreate: a particle that is a corner of no lattice cell
    with four corners in the disc (the four points where the circle meets the lattice's
    axes on a square lattice) is not part of the cloth. The particles outside never
    move. A polygon outline is not rebuilt here (all particles)."""
    if shape != "circle":
        return np.ones((my, mx), dtype=bool)
    a = (np.arange(mx) - 0.5 * (mx - 1)) / (0.5 * (mx - 1)) if mx > 1 else np.zeros(1)
    b = (np.arange(my) - 0.5 * (my - 1)) / (0.5 * (my - 1)) if my > 1 else np.zeros(1)
    disc = a[None, :] ** 2 + b[:, None] ** 2 <= 1 + 1e-12
    cell = disc[:-1, :-1] & disc[:-1, 1:] & disc[1:, :-1] & disc[1:, 1:]
    corner = np.zeros_like(disc)
    corner[:-1, :-1] |= cell
    corner[:-1, 1:] |= cell
    corner[1:, :-1] |= cell
    corner[1:, 1:] |= cell
    return disc & corner


def load(path, frames=True):
    """Load a drape HDF5 file; raise ValueError if it is missing or not drape's.
    frames=False: all but the positions and velocities (theirs of no frame, [0, My,
    Mx, 3]; read a frame from /position yourself, as a large run's file asks)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r", locking=False)
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
        t = f["time"][:n].reshape(n)
        # a run killed inside a frame's write can leave /time one longer than what was
        # written (extended before the value, which stays at the fill value 0)
        while n > 1 and t[n - 1] == 0 and t[n - 2] > 0:
            n -= 1
        pos = f["position"]
        if pos.ndim != 4 or pos.shape[3] != 3 or pos.shape[0] < n:
            raise ValueError(f"{path}: /position has shape {pos.shape}, expected [>={n}][My][Mx][3]")
        return DrapeRun(
            path=path,
            positions=pos[:n] if frames else np.empty((0,) + pos.shape[1:]),
            velocities=f["velocity"][:n] if frames else np.empty((0,) + pos.shape[1:]),
            time=f["time"][:n].reshape(n),
            step=f["step"][:n].reshape(n).astype(np.int64),
            energies={e: _series(f, f"energy_{e}", n) for e in ENERGIES if f"energy_{e}" in f},
            attrs={k: _decode(v) for k, v in f.attrs.items()},
            contact={c: _series(f, f"contact_{c}", n) for c in CONTACT if f"contact_{c}" in f},
            strain_max=_series(f, "strain_max", n) if "strain_max" in f else None,
            solid_triangles=_triangles(f),
            active=_active(f, pos.shape[1], pos.shape[2], path),
        )


def _series(f, name, n):
    """The first n rows of a per-frame dataset: [n] for one value a frame, else [n, k]."""
    d = f[name][:n]
    return d.reshape(n) if d.shape[1:] == (1,) else d.reshape(n, -1)


def _active(f, my, mx, path):
    """/active (written by drape since the cut outline's spikes were pruned) as [My, Mx]
    bool, or None for an older file (then active_mask rebuilds it)."""
    if "active" not in f:
        return None
    a = np.asarray(f["active"][...]).ravel()
    if a.size != mx * my:
        raise ValueError(f"{path}: /active has {a.size} entries, expected {my} x {mx}")
    return a.reshape(my, mx) != 0


def _triangles(f):
    """/solid_triangles (flat, 9 reals per triangle) as [ntri, 3, 3], or None."""
    if "solid_triangles" not in f:
        return None
    t = np.asarray(f["solid_triangles"][...], dtype=float).ravel()
    if t.size == 0 or t.size % 9:
        return None
    return t.reshape(-1, 3, 3)
