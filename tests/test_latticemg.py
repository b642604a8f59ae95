"""Geometric multigrid on the lattice (-pc_type latticemg, src/integrate/pclatticemg.c):
CG iterations that do not grow with the lattice, the same step as a direct solve
(with the solid's constraints filtering the interpolation), drapebe's switch to it
on one rank and on several, and its refusals."""
import numpy as np

from conftest import refused, run

import drape_h5

HANG = "-cloth_fabric denim -cloth_size 0.3 -cloth_pin edge_corners -ts_type drapebe -ts_dt 1e-2 -ts_max_steps 30 -output_interval 1"


def switch_of(args):
    """A run's report, and the mean of block IC's iterations its note on the switch to
    the multigrid gives (None: no switch)."""
    res = run(args, checks=False)
    note = res.stdout.split("CG with block IC took ")
    return res.report, float(note[1].split()[0]) if len(note) > 1 else None


def test_iterations_do_not_grow_with_the_lattice():
    """Denim, 30 cm, hanging from two corners at 1e-2 s (a stiff step): on 33^2 and
    65^2 (four times the particles) CG with the lattice multigrid takes at most 1.5
    times the iterations a step (measured: 7.6 and 9.5) where block IC's nearly double
    (102 and 206); and drapebe, left to choose, gives block IC up for it with a note
    once a solve takes more than the threshold (-drape_mg_its 10 here: at step 4,
    after 3 solves, not 10, where the mean is more than twice it)."""
    cg = {}
    for n in (33, 65):
        for pc in ("latticemg", "blockicc"):
            cg[n, pc] = run(f"{HANG} -da_grid_x {n} -da_grid_y {n} -pc_type {pc}").report["cg_per_step"]
    assert cg[65, "latticemg"] <= 1.5 * cg[33, "latticemg"], cg
    assert cg[65, "blockicc"] > 1.7 * cg[33, "blockicc"], cg
    assert cg[65, "latticemg"] < 0.1 * cg[65, "blockicc"], cg
    early = run(f"{HANG} -da_grid_x 33 -da_grid_y 33 -drape_mg_its 10")
    assert early.report["pc_type"] == "latticemg" and 0 < early.report["pc_switched_step"] <= 9, early.report
    assert "the run goes on with geometric multigrid on the lattice (latticemg)" in early.stdout
    held = run(f"{HANG} -da_grid_x 33 -da_grid_y 33 -drape_mg_its 0").report
    assert held["pc_type"] == "blockicc" and held["pc_switched_step"] == -1, held


def test_a_held_block_ic_is_made_again_when_its_solves_grow():
    """drapebe's block IC is made every -drape_pc_lag steps (5), and again at the next
    solve once a solve takes more than 4 CG iterations more than the one after it was
    made. The hang above at 33^2 swings: a factorisation held for 5 steps took 6, 15,
    33, 104, 106 iterations (100.7 a step over 30 steps); made again so, 28.4 a step,
    below the threshold of the switch to the multigrid (40), so drapebe keeps block
    IC, as a factorisation made every step (-drape_pc_lag 1: 18 a step) would."""
    held = run(f"{HANG} -da_grid_x 33 -da_grid_y 33 -drape_mg_its 0").report
    assert held["pc_type"] == "blockicc" and held["cg_per_step"] < 45, held
    auto = run(f"{HANG} -da_grid_x 33 -da_grid_y 33").report
    assert auto["pc_type"] == "blockicc" and auto["pc_switched_step"] == -1 and auto["cg_per_step"] < 40, auto
    every = run(f"{HANG} -da_grid_x 33 -da_grid_y 33 -drape_pc_lag 1").report
    assert every["cg_per_step"] < auto["cg_per_step"] < 2 * every["cg_per_step"], (every, auto)


def test_a_large_lattice_takes_the_multigrid_sooner():
    """The switch's threshold: 40 iterations a solve, 20 on a lattice of 40 000
    particles or more (the coarse levels pay sooner there). The hang of denim at a
    step where block IC takes 20-40 iterations a solve: on 121^2 (2.5 ms; measured 24
    a step) it keeps block IC; on 201^2 (2 ms; 44, 26, 23, ... a solve) it takes the
    multigrid after its 10 solves (at a mean of 29), unless -drape_mg_its 40 is
    given. CG at -ksp_rtol alone (-drape_solve_error 0), as the switch was measured:
    stopped at the step's own accuracy, block IC takes 11.7 a step on 121^2 here,
    below both thresholds."""
    small = run(f"{HANG} -da_grid_x 121 -da_grid_y 121 -ts_dt 2.5e-3 -ts_max_steps 12 -drape_solve_error 0", checks=False).report
    assert small["pc_switched_step"] == -1 and 20 < small["cg_per_step"] < 40, small
    large = f"{HANG} -da_grid_x 201 -da_grid_y 201 -ts_dt 2e-3 -ts_max_steps 12 -drape_solve_error 0"
    rep, mean = switch_of(large)
    assert 2 <= rep["pc_switched_step"] <= 9 and rep["pc_type"] == "latticemg" and 20 < mean < 40, (rep, mean)
    held, _ = switch_of(f"{large} -drape_mg_its 40")
    assert held["pc_switched_step"] == -1 and held["pc_type"] == "blockicc" and 20 < held["cg_per_step"] < 40, held


def test_at_the_steps_accuracy_a_large_lattice_switches_at_8():
    """Where CG stops at the step's own accuracy (-drape_solve_error, the default)
    block IC takes 2-3 x fewer iterations than at -ksp_rtol alone, and on a lattice
    of 40 000 particles or more the threshold is 8 instead of 20. The 201^2 hang of
    the test above, at drape's defaults: block IC's first solves take more than
    twice 8 (measured 21.5 a solve) and the run goes on with the multigrid at step
    2; with the threshold of 20 it keeps block IC, under 20 iterations a step
    (measured 8.42), where the multigrid pays on a long run; below 40 000 particles
    (121^2, 11.4 a step) the threshold stays 40 (at 8 this run would switch, at step
    9)."""
    large = f"{HANG} -da_grid_x 201 -da_grid_y 201 -ts_dt 1.5e-3 -ts_max_steps 12"
    rep, mean = switch_of(large)
    assert rep["pc_switched_step"] == 2 and rep["pc_type"] == "latticemg" and 16 < mean < 40, (rep, mean)
    held, _ = switch_of(f"{large} -drape_mg_its 20")
    assert held["pc_switched_step"] == -1 and held["pc_type"] == "blockicc" and 6 < held["cg_per_step"] < 20, held
    small, _ = switch_of(f"{HANG} -da_grid_x 121 -da_grid_y 121 -ts_dt 2.5e-3 -ts_max_steps 12")
    assert small["pc_switched_step"] == -1 and 8 < small["cg_per_step"] < 20, small


def test_solves_the_step_a_direct_solve_does(tmp):
    """CG with the multigrid to a tight tolerance gives backward Euler's step as the
    sparse Cholesky factorisation does: the hang, and a drop onto a sphere with
    friction, whose sliding particles' normal direction the interpolation filters
    out (a coarse correction along it would undo the constraint)."""
    drop = "-da_grid_x 24 -da_grid_y 24 -ts_type drapebe -ts_dt 2e-3 -ts_max_time 0.3 -output_interval 0.1 -solid_type sphere -solid_radius 0.25 -contact_mode friction -contact_thickness 0.005 -cloth_center 0,0,0.3"
    for name, scene in (("hang", f"{HANG} -da_grid_x 24 -da_grid_y 24 -ts_max_steps 5 -output_interval 1e-2"), ("drop", drop)):
        mg, direct = tmp / f"{name}-mg.h5", tmp / f"{name}-direct.h5"
        rep = run(f"{scene} -pc_type latticemg -ksp_rtol 1e-12 -output_file {mg}").report
        run(f"{scene} -ksp_type preonly -pc_type cholesky -drape_mat_type aij -output_file {direct}")
        a, b = drape_h5.load(mg), drape_h5.load(direct)
        assert rep["pc_type"] == "latticemg" and len(a.time) == len(b.time) >= 4
        d = np.abs(a.positions - b.positions).max()
        if name == "hang":
            assert d < 1e-10, d
        else:  # after the landing the contacts' active sets amplify the solves' last digits: as much as block IC's
            icc = tmp / "drop-icc.h5"
            run(f"{scene} -pc_type blockicc -ksp_rtol 1e-12 -output_file {icc}")
            d_icc = np.abs(drape_h5.load(icc).positions - b.positions).max()
            assert d < max(5 * d_icc, 1e-7) and d < 1e-5, (d, d_icc)
            assert np.abs(a.positions[:3] - b.positions[:3]).max() < 1e-8  # before it lands
            assert rep["strain_max"] < 0.05 and a.positions[-1, ..., 2].max() < 0.3, rep  # it landed


def test_an_indefinite_v_cycle_gives_way_to_the_hybrid_cycle(tmp):
    """The V(1,1) cycle is positive definite only where 2 M - A is (M: block IC of the
    finest level). The Cusick scene on 33^2 at 4 ms steps: block IC(0) of the stiff
    step misses A by more than 2 in some direction (b.Bb = -0.18 b.M^-1 b at the
    failing solve on 81^2; with the V-cycle on the coarse levels, -pc_latticemg_gamma 1:
    the default W-cycle's coarse correction happens to keep this run positive, the
    smoother's term M^-1 (2 M - A) M^-1 is the same; and with the releases solved
    again, -contact_release_next 0, as it was measured), CG stops with an indefinite
    preconditioner, and drapebe
    makes the same solve again with the hybrid cycle, positive definite for any
    positive definite M: no step is retried. The hybrid cycle itself solves the
    step the direct solve does. CG at -ksp_rtol alone and a new matrix every step
    (-drape_solve_error 0 -drape_matrix_keep 0), as it was measured: either changes the
    path, and this run then meets no such direction."""
    res = run("-options_file runs/cusick.opts -cloth_fabric denim -da_grid_x 33 -da_grid_y 33 -ts_dt 4e-3 -ts_max_time 0.5 -pc_type latticemg -pc_latticemg_gamma 1 -contact_release_next 0 -drape_solve_error 0 -drape_matrix_keep 0 -output_interval 0.5", checks=False)
    assert "the run goes on with its hybrid cycle, positive definite" in res.stdout and "DIVERGED_INDEFINITE_PC" in res.stdout, res.stdout[-3000:]
    assert res.report["steps_retried"] == 0 and res.report["strain_max"] < 0.02, res.report
    scene = f"{HANG} -da_grid_x 24 -da_grid_y 24 -ts_max_steps 5 -output_interval 1e-2"
    run(f"{scene} -pc_type latticemg -pc_latticemg_hybrid -ksp_rtol 1e-12 -output_file {tmp / 'h.h5'}")
    run(f"{scene} -ksp_type preonly -pc_type cholesky -drape_mat_type aij -output_file {tmp / 'd.h5'}")
    assert np.abs(drape_h5.load(tmp / "h.h5").positions - drape_h5.load(tmp / "d.h5").positions).max() < 1e-10


def test_refusals():
    """Options out of range end with one sentence each."""
    base = "-ts_type drapebe -pc_type latticemg"
    refused(f"{base} -pc_latticemg_levels 1", "-pc_latticemg_levels 1 is not a multigrid")
    refused(f"{base} -pc_latticemg_coarse_nodes 0", "-pc_latticemg_coarse_nodes 0 is outside [1, 1000]")
    refused(f"{base} -pc_latticemg_coarse_lag 0", "-pc_latticemg_coarse_lag 0 is not a number of set-ups")
    refused(f"{base} -pc_latticemg_gamma 3", "-pc_latticemg_gamma 3 is not a cycle: give 1 (V) or 2 (W)")
    refused(f"{base} -pc_latticemg_smoother sgs -pc_latticemg_hybrid", "-pc_latticemg_hybrid needs the block IC smoother")
    refused("-ts_type drapebe -drape_mg_its -1", "-drape_mg_its must be zero or positive")


def test_on_several_ranks(tmp):
    """On several ranks each rank restricts its rows, the restricted residual is summed
    over the ranks, and every rank holds the coarse levels whole; the first coarse
    operator sums each rank's rows' share, the blocks in other ranks' columns (read
    with their columns' nodes and constraints from their owners) included. The
    finest level's block IC is each rank's own block (block Jacobi). The hang of
    test_iterations_do_not_grow_with_the_lattice on 33^2 (measured: 6.9, 10.6 and
    16.6 CG iterations a step on 1, 2 and 3 ranks; without the other ranks' columns
    in the coarse operator 23.7 and 41; block IC alone on 2 ranks 178); the step of
    the direct solve on 2 and 3 ranks, the sphere drop's sliding particles too. And
    drapebe, left to choose on 2 ranks, gives its additive Schwarz up for it as one
    rank gives block IC up (CG at -ksp_rtol alone: at step 9, 57 iterations a solve;
    at the step's accuracy it takes 42 a solve, near the threshold of 40)."""
    scene = f"{HANG} -da_grid_x 33 -da_grid_y 33 -ts_max_steps 10 -pc_type latticemg"
    cg = {np_: run(scene, np_=np_).report["cg_per_step"] for np_ in (1, 2, 3)}
    assert cg[2] <= 2 * cg[1] and cg[3] <= 3 * cg[1], cg
    assert cg[2] < 0.15 * run(f"{HANG} -da_grid_x 33 -da_grid_y 33 -ts_max_steps 10 -pc_type blockicc", np_=2).report["cg_per_step"], cg
    auto = run(f"{HANG} -da_grid_x 33 -da_grid_y 33 -ts_max_steps 12 -drape_solve_error 0", np_=2)
    assert auto.report["pc_type"] == "latticemg" and 0 < auto.report["pc_switched_step"] <= 9, auto.report
    assert "the run goes on with geometric multigrid on the lattice (latticemg)" in auto.stdout
    drop = "-da_grid_x 24 -da_grid_y 24 -ts_type drapebe -ts_dt 2e-3 -ts_max_time 0.3 -output_interval 0.1 -solid_type sphere -solid_radius 0.25 -contact_mode friction -contact_thickness 0.005 -cloth_center 0,0,0.3"
    for name, sc in (("hang", f"{HANG} -da_grid_x 24 -da_grid_y 24 -ts_max_steps 5 -output_interval 1e-2"), ("drop", drop)):
        direct = tmp / f"{name}-direct.h5"
        run(f"{sc} -ksp_type preonly -pc_type cholesky -drape_mat_type aij -output_file {direct}")
        b = drape_h5.load(direct)
        for np_ in (2, 3):
            mg = tmp / f"{name}-mg{np_}.h5"
            rep = run(f"{sc} -pc_type latticemg -ksp_rtol 1e-12 -output_file {mg}", np_=np_).report
            a = drape_h5.load(mg)
            assert rep["pc_type"] == "latticemg" and len(a.time) == len(b.time) >= 4
            d = np.abs(a.positions - b.positions).max()
            assert d < (1e-10 if name == "hang" else 1e-5), (name, np_, d)


def test_a_gauss_seidel_v_cycle_that_fails_is_a_failed_solve():
    """With -pc_latticemg_smoother sgs the V-cycle has no hybrid cycle to fall back on
    (it needs a symmetric smoother). Where CG finds that V-cycle indefinite (the hang
    at 24^2 and 1e-2 s, from about step 6) the solve failed like any other, and the
    step is retried smaller: 30 steps, 5 retried. drapebe used to ask the multigrid
    for its hybrid cycle there, and the run ended with the multigrid's refusal."""
    res = run("-options_file runs/hang.opts -cloth_damping 5 -da_grid_x 24 -da_grid_y 24 -ts_dt 1e-2 -ts_max_steps 30 -output_interval 1 "
              "-pc_type latticemg -pc_latticemg_smoother sgs")
    assert "needs the block IC smoother" not in res.stdout + res.stderr
    assert res.report["steps"] == 30 and res.report["steps_retried"] >= 1, res.report
