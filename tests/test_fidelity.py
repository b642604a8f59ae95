"""Fabric fidelity: drape against the classical fabric tests. The heavy elastica
(scripts/elastica.py) against its known answers, drape's clamped strip
(scripts/cantilever.py, Peirce's cantilever) against the elastica, and the virtual
KES tensile, shear and picture-frame tests (scripts/kes.py) against Y and G."""
import math
import sys

import numpy as np
import pytest

from conftest import DRAPE, ROOT

sys.path.insert(0, str(ROOT / "scripts"))
import cantilever  # noqa: E402
import elastica  # noqa: E402
import kes  # noqa: E402


def test_elastica_small_deflection_limit():
    """For w L^3 / B << 1 the strip is the linear beam: drop w L^4 / (8 B), reach L, clamp
    slope w L^3 / (2 B)."""
    for lam in (1e-3, 1e-2):
        e = elastica.solve(lam)
        assert e.drop == pytest.approx(lam / 8, rel=1e-4)
        assert e.slope0 == pytest.approx(lam / 2, rel=1e-4)
        assert e.reach == pytest.approx(1, abs=1e-5)


def test_elastica_matches_its_perturbation_expansion():
    """The next terms, derived by hand in elastica.py's docstring: drop/L = lam/8 - lam^3/640,
    reach/L = 1 - lam^2/112, L theta'(0) = lam/2 - lam^3/320. At lam = 0.3 the
    remainders are O(lam^5), O(lam^4) (measured 8e-8, 1.5e-6, 1.5e-7), far below the
    terms they follow (4e-5, 8e-4, 8e-5): a wrong nonlinear term shows."""
    lam = 0.3
    e = elastica.solve(lam)
    assert abs(e.drop - (lam / 8 - lam ** 3 / 640)) < 3e-7
    assert abs(e.reach - (1 - lam ** 2 / 112)) < 4e-6
    assert abs(e.slope0 - (lam / 2 - lam ** 3 / 320)) < 5e-7


@pytest.mark.parametrize("lam", [8.0, 50.0])
def test_elastica_moment_balance_at_the_clamp(lam):
    """The clamp carries the weight's moment, B theta'(0) = w int_0^L x ds, which the
    shooting (on the differentiated equation and theta'(L) = 0) must reproduce; and at
    large lambda it finds the hanging branch (0 <= theta < pi/2, theta' >= 0), not a
    strip curled up and over."""
    e = elastica.solve(lam)
    assert e.slope0 == pytest.approx(lam * np.trapezoid(e.x, e.sigma), rel=1e-5)
    assert e.theta.min() >= 0 and e.theta.max() < math.pi / 2 and np.all(np.diff(e.theta) >= 0)


def test_elastica_against_astm_d1388_and_peirce():
    """ASTM D1388 reads the bending length c = (B/w)^(1/3) as half the overhang whose chord
    is at 41.5 deg: the elastica at L = 2c (lambda = 8) has its chord at 41.5 deg. Peirce's
    c = L (cos(phi/2) / (8 tan phi))^(1/3) is an approximation: exact at small angles
    (within 0.05 % at 5 deg), 1.9 % high at 41.5 deg."""
    assert math.degrees(elastica.solve(8.0).chord_angle) == pytest.approx(41.5, abs=0.05)
    assert abs(elastica.peirce_error(math.radians(5))) < 5e-4
    assert 0.01 < elastica.peirce_error(math.radians(41.5)) < 0.03


def test_frictional_elastica_known_answers():
    """Grosberg's elastic-frictional strip (elastica.solve_frictional): without friction
    it is the elastica (to 1e-9); at small lambda it is the beam that bends only where
    the weight's moment w (L - s)^2 / 2 exceeds HB, drop / L = (lambda/2) ((s_y - (1 -
    a^4)/4)/3 - a^2 s_y^2/2 + a ((1 - a^3)/3 - a^2 s_y)) with a = (2 eta / lambda)^(1/2),
    s_y = 1 - a (integrated by hand; measured 4e-7 off at lambda = 0.01); a friction
    moment above the flat strip's clamp moment (eta >= lambda/2) holds it flat; and more
    friction reaches further."""
    for lam in (8.0, 42.8):
        a, b = elastica.solve(lam), elastica.solve_frictional(lam, 0.0)
        assert b.drop == pytest.approx(a.drop, rel=1e-9) and b.reach == pytest.approx(a.reach, rel=1e-9)
    lam, eta = 0.01, 0.002
    a = math.sqrt(2 * eta / lam)
    sy = 1 - a
    drop = lam / 2 * ((sy - (1 - a ** 4) / 4) / 3 - a * a * sy * sy / 2 + a * ((1 - a ** 3) / 3 - a * a * sy))
    assert elastica.solve_frictional(lam, eta).drop == pytest.approx(drop, rel=1e-5)
    flat = elastica.solve_frictional(8.0, 4.0)
    assert flat.drop == 0 and flat.reach == 1
    reach = [elastica.solve_frictional(42.8, eta, n=1000).reach for eta in (0.0, 1.0, 2.0, 3.0)]
    assert all(r0 < r1 for r0, r1 in zip(reach, reach[1:])), reach


@pytest.mark.parametrize("angle", [0, 90])
@pytest.mark.parametrize("model", ["paper", "drape"])
def test_cantilever_strip_rests_on_the_elastica(angle, model):
    """A denim strip (25 mm wide) cut along the warp (0 deg) or the weft (90 deg), clamped
    by four pinned rows, its free length L = 2 c (lambda = 8, the ASTM chord of 41.5 deg):
    its tip at rest lies within 5 % of the elastica's drop and reach (the issue's floor)
    with 5 free rows and with 10. The clamp is the midpoint of the last pinned segment
    (cantilever.py): taking the last pinned particle instead would put the 10-row
    elastica 11 % lower and fail. Both models converge (the error falls with the
    spacing): the paper's (thread triples only) to the elastica (measured -0.85 % /
    -0.2 % in the drop at 5 / 10 rows); drape's, whose diagonal triples couple the
    curvatures (D12, a plate's Poisson effect), to a strip that curls across a little
    (anticlastic bending): +0.65-0.82 % / +0.46-0.52 % in the drop at 5 / 10 rows,
    +0.44-0.55 % at 20."""
    err = {}
    for n in (5, 10):
        r = cantilever.run_case(angle, n, lam=8.0, fabric=("-cloth_fabric", "denim", "-cloth_model", model), drape=DRAPE)
        assert r["at_rest"], r
        assert abs(r["drop_err"]) < 0.05 and abs(r["reach_err"]) < 0.05, r
        err[n] = max(abs(r["drop_err"]), abs(r["reach_err"]))
    assert err[10] < (0.5 if model == "paper" else 0.7) * err[5], err


def test_bias_strip_bends_with_the_bias_rigidity():
    """A denim strip cut at 45 degrees to the threads (ARCSim's measured bias row: Bb =
    18.3e-6 N m, 0.91 of the threads' mean) rests within 5 % of the elastica with Bb at
    10 and 20 free rows (measured -0.6 % / +2.6 % in the drop; it bends at 1.01, 0.94
    Bb, and 0.95, 0.96 Bb at 40, 80 rows: the strip's edges curl a little, which a
    wide plate's inextensibility would forbid). The paper's model, without twist
    rigidity, bends it at about 0.4 of the threads' mean (at most (Bw + Bf)/4 in the
    continuum). The clamp needs four pinned rows (cantilever.py): along a 45 degree
    strip a diagonal triple spans two rows, and with two pinned rows every diagonal
    line along the strip is hinged at the clamp, not held: the strip bends at 0.71 Bb
    at 20 rows (measured)."""
    fab = ("-cloth_fabric", "denim")
    paper = cantilever.run_case(45, 20, fabric=fab + ("-cloth_model", "paper"), drape=DRAPE)
    hinged = cantilever.run_case(45, 20, fabric=fab, k=2, drape=DRAPE)
    cases = [cantilever.run_case(45, n, fabric=fab, drape=DRAPE) for n in (10, 20)]
    bb = cases[0]["B"]
    assert bb == pytest.approx(73.384567e-6 / 4)
    assert all(r["at_rest"] for r in (paper, hinged, *cases))
    for r in cases:
        assert abs(r["drop_err"]) < 0.05 and abs(r["reach_err"]) < 0.05, r
    assert paper["B_eff_ratio"] * paper["B"] < 0.5 * bb, paper
    assert hinged["B_eff_ratio"] < 0.8 < cases[1]["B_eff_ratio"], (hinged, cases[1])


@pytest.mark.parametrize("mode", ["tensile-warp", "tensile-weft"])
def test_kes_tensile_gives_y(mode):
    """KES-FB1 tensile: clamps 20 cm long, 5 cm apart (10 cells), the far one pulled 1 %
    across them; the free particles start unstrained. At rest the cloth stores
    Y e^2 W H / 2 with denim's Y along the pull (411, 2028 N/m): exact in this model
    (no Poisson coupling, every row a chain of equal springs), so within the solver's
    tolerance, far inside the issue's 2 %."""
    r = kes.clamp_test(mode, drape=DRAPE)
    assert r["at_rest"], r
    assert abs(r["error"]) < 1e-4, r
    assert r["energy"]["shear"] < 1e-9 * r["energy"]["stretch"]


def test_picture_frame_shear_gives_g():
    """Picture frame: all four edges pinned on the trellis of a 0.01 rad shear (sides
    unstretched), the interior starting unsheared. It comes to the uniform shear,
    G gamma^2 A / 2 with denim's G = s_sh = 53.4 N/m, and stretches nothing."""
    r = kes.clamp_test("frame", drape=DRAPE)
    assert r["at_rest"], r
    assert abs(r["error"]) < 1e-4, r
    assert r["energy"]["stretch"] < 1e-9 * r["energy"]["shear"]


def test_kes_shear_gives_g():
    """KES-FB1 shear: the far clamp moved 0.01 rad along itself. The specimen's free ends
    carry no shear stress and relax over an end zone, so the rectangle stores less
    than G gamma^2 W H / 2 by a share proportional to W / H: measured -4.0 % at KES's
    H/W = 4, -1.8 % at 8. Both within the issue's 5 %, and the W/H -> 0 extrapolation,
    2 G(8) - G(4), within 1 % of G (measured +0.4 %)."""
    g = {}
    for aspect in (4, 8):
        r = kes.clamp_test("shear", aspect=aspect, drape=DRAPE)
        assert r["at_rest"] and r["out_of_plane"] == 0, r
        assert -0.05 < r["error"] < 0, r
        g[aspect] = r["measured"]
    assert g[8] > g[4]
    assert 2 * g[8] - g[4] == pytest.approx(r["expected"], rel=0.01), (g, r["expected"])
