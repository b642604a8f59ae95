"""Verification: known answers, orders of accuracy, conservation, stability limits."""
import numpy as np
import pytest

from conftest import rest_shape, run

import drape_h5

SCHEMES = {
    "euler": "-ts_type euler",
    "symplectic": "-ts_type basicsymplectic",
    "beuler": "-ts_type drapebe -ksp_rtol 1e-13",
}

# A small, soft hanging cloth: smooth motion, cheap to integrate.
SOFT = ("-da_grid_x 8 -da_grid_y 8 -cloth_pin edge_corners -cloth_stretch 50 -cloth_shear 5 "
        "-cloth_bend 1e-3 -cloth_damping 0.5 -output_interval 0 -output_steps 1000000")


@pytest.mark.parametrize("scheme", SCHEMES)
def test_free_fall_follows_the_discrete_formula(tmp, scheme):
    """An unpinned flat cloth falls rigidly: internal forces cancel, and every particle
    follows the scheme's own recurrence for x'' = g - c x' to round-off."""
    h, c, g, n = 0.01, 0.3, -9.81, 40
    out = tmp / "fall.h5"
    # lattice spacing 0.25 m: positions are exact binary numbers, so internal forces
    # start exactly at zero; a soft material keeps explicit Euler from amplifying the
    # round-off of the falling positions into a divergence within the run
    run(f"-da_grid_x 6 -da_grid_y 5 -cloth_size 1.25,1 -cloth_stretch 1 -cloth_shear 0.1 -cloth_bend 1e-6 "
        f"-cloth_damping {c} -ts_dt {h} -ts_max_steps {n} -ts_max_time 10 "
        f"-output_steps 1 -output_interval 0 -output_file {out} {SCHEMES[scheme]}")
    fr = drape_h5.load(out)
    z, v = 0.0, 0.0
    expect = [0.0]
    for _ in range(n):
        if scheme == "euler":
            z, v = z + h * v, v + h * (g - c * v)
        elif scheme == "symplectic":
            v = v + h * (g - c * v)
            z = z + h * v
        else:
            v = (v + h * g) / (1 + h * c)
            z = z + h * v
        expect.append(z)
    dz = fr.positions[:, :, :, 2] - fr.positions[0, :, :, 2]
    assert len(fr.time) == n + 1
    assert np.abs(dz - np.array(expect)[:, None, None]).max() < 1e-10 * abs(expect[-1])
    assert np.abs(fr.positions[:, :, :, :2] - fr.positions[0, :, :, :2]).max() < 1e-12


def final_positions(tmp, name, args):
    out = tmp / f"{name}.h5"
    run(f"{SOFT} -ts_max_time 0.1 -output_file {out} {args}", checks=False)
    return drape_h5.load(out).positions[-1]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """RK4 with a step 2.5x below the smallest tested one: its error (~1e-17 m) is
    far below the errors measured (>1e-6 m)."""
    return final_positions(tmp_path_factory.mktemp("ref"), "ref", "-ts_type rk -ts_rk_type 4 -ts_adapt_type none -ts_dt 1e-5")


@pytest.mark.parametrize("scheme,order", [("euler", 1), ("symplectic", 1), ("beuler", 1), ("rk2", 2)])
def test_observed_order_of_accuracy(tmp, reference, scheme, order):
    """Error at t = 0.1 s against an RK4 reference falls with the scheme's order as the
    step halves."""
    args = {**SCHEMES, "rk2": "-ts_type rk -ts_rk_type 2a -ts_adapt_type none"}[scheme]
    ref = reference
    steps = [1e-4, 5e-5, 2.5e-5] if order == 1 else [4e-4, 2e-4, 1e-4]
    err = [np.abs(final_positions(tmp, f"h{i}", f"{args} -ts_dt {h}") - ref).max() for i, h in enumerate(steps)]
    observed = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    assert np.all(np.abs(observed - order) < 0.1), f"errors {err}, observed orders {observed}"


def energy_drift(tmp, scheme, h, steps):
    out = tmp / f"{scheme}.h5"
    run(f"-da_grid_x 6 -da_grid_y 6 -cloth_pin edge_corners -cloth_stretch 50 -cloth_shear 5 -cloth_bend 1e-3 "
        f"-cloth_damping 0 -ts_dt {h} -ts_max_steps {steps} -ts_max_time 1e9 -output_interval 0 "
        f"-output_steps 100 -drape_divergence_factor 1e6 -output_file {out} {SCHEMES[scheme]}")
    fr = drape_h5.load(out)
    e = fr.total_energy()
    scale = fr.attrs["mass"] * 9.81 * 1.0
    return np.abs(e - e[0]) / scale


def test_symplectic_energy_bounded_explicit_energy_grows(tmp):
    """Without damping over 10^4 steps: symplectic Euler's energy error stays small and
    does not grow; explicit Euler's grows steadily."""
    h, n = 1e-4, 10000
    symp = energy_drift(tmp, "symplectic", h, n)
    expl = energy_drift(tmp, "euler", h, n)
    half = len(symp) // 2
    assert symp.max() < 0.05
    assert symp[half:].max() < 2.0 * symp[:half].max() + 1e-12
    assert expl[-1] > 20 * symp.max()
    quarters = np.array_split(expl, 4)
    assert all(quarters[k + 1].mean() > quarters[k].mean() for k in range(3)), expl


def test_symplectic_stability_limit(tmp):
    """Symplectic Euler is stable just below the printed 2/Omega_max limit and diverges
    just above it, where drape stops with a message naming the step and the limit."""
    # weak gravity: the cloth barely deforms, so Omega_max stays what it was at t = 0
    base = ("-da_grid_x 8 -da_grid_y 8 -cloth_pin edge_corners -cloth_damping 0 -ts_type basicsymplectic "
            "-gravity 0,0,-0.1 -drape_stability_its 400 -ts_max_time 1e9")
    limit = run(f"{base} -ts_max_steps 0").report["symplectic_limit"]
    run(f"{base} -ts_dt {0.97 * limit} -ts_max_steps 3000")
    bad = run(f"{base} -ts_dt {1.03 * limit} -ts_max_steps 3000", check=False)
    assert bad.returncode != 0
    assert "diverged at step" in bad.stderr and f"{limit:.4e}" in bad.stderr, bad.stderr
    assert "PETSC ERROR" not in bad.stderr


def test_assembled_jacobian_matches_finite_differences():
    """-snes_test_jacobian: the assembled backward-Euler matrix (exact Hessian) agrees
    with a finite-difference Jacobian of the residual at every Newton step."""
    res = run("-da_grid_x 6 -da_grid_y 5 -cloth_pin edge_corners -ts_type drapebe -snes_type newtonls "
              "-cloth_hessian exact -ts_dt 5e-3 -ts_max_steps 4 -snes_test_jacobian", checks=False)
    ratios = [float(r) for r in __import__("re").findall(r"\|\|J - Jfd\|\|_F/\|\|J\|\|_F = (\S+),", res.stdout)]
    assert len(ratios) >= 4, res.stdout
    assert max(ratios) < 1e-6, ratios


def test_rest_shape_is_resolution_independent(tmp):
    """The material is given as continuum rigidities (N/m, N m) and converted with
    the lattice spacing, so the same cloth hanging at rest on a 21 x 21 and a
    41 x 41 lattice takes nearly the same shape: matched particles within 2.5 cm
    (1.4 cm measured) and 1 cm RMS (0.6 cm) on a 1 m cloth."""
    shapes = {n: rest_shape(tmp, n, "-options_file runs/hang.opts") for n in (21, 41)}
    d = shapes[21] - shapes[41][::2, ::2]
    assert np.abs(d).max() < 0.025 and np.sqrt((d ** 2).sum(-1).mean()) < 0.01
    assert shapes[21][..., 2].min() < 0.1  # it did hang
