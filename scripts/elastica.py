#!/usr/bin/env python3
"""The heavy elastica: a strip clamped horizontally at one end, bent by its own weight
(Peirce's cantilever, ASTM D1388, FAST).

Derivation. A strip of free length L, weight w = rho g per unit area and bending
rigidity B per unit width (both per unit width from here on), is clamped
horizontally at arclength s = 0. Let theta(s) be the angle of its tangent below the
horizontal and x(s), y(s) its horizontal reach and drop, x' = cos theta,
y' = sin theta. The bending moment carried at s is B theta'(s) (Euler-Bernoulli,
inextensible) and balances the moment, about the point at s, of the weight of the
part beyond it:

    B theta'(s) = w int_s^L (x(t) - x(s)) dt.

Differentiating once (the integrand vanishes at t = s):

    B theta''(s) = -w (L - s) cos theta(s),    theta(0) = 0,    theta'(L) = 0,

the second condition saying that the free end carries no moment. With sigma = s / L
and lambda = w L^3 / B the problem has one parameter:

    theta''(sigma) = -lambda (1 - sigma) cos theta,   theta(0) = 0,  theta'(1) = 0,

and the tip sits at drop / L = int_0^1 sin theta, reach / L = int_0^1 cos theta.
It is solved here by shooting on p = theta'(0): RK4 on a uniform grid (default 1000
steps: the tip is then exact to about 1e-12) for (theta, theta', x, y) and the
sensitivity (d theta/dp, d theta'/dp), Newton on theta'(1) = 0 kept inside the
bracket [0, lambda/2], bisecting every other step. On the hanging solution
theta' >= 0 (B theta' is the weight's moment), so a shot whose theta' turns
negative before the tip counts as too low (at large lambda, p near 0 curls the strip
up and over onto another, unstable, root), and theta'(1) >= 0 at p = lambda/2 since
cos theta <= 1.

Known answers (tests/test_fidelity.py). Expanding in lambda (theta = lambda theta_1
+ lambda^3 theta_3 + ...; theta_1 = (1 - (1 - sigma)^3)/6 is the small-deflection
beam) gives

    drop / L = lambda/8 - lambda^3/640 + O(lambda^5),
    reach / L = 1 - lambda^2/112 + O(lambda^4),
    L theta'(0) = lambda/2 - lambda^3/320 + O(lambda^5),

the first term the textbook w L^4 / (8 B); and, integrating the moment balance from
the clamp, L theta'(0) = lambda int_0^1 x(sigma) d sigma. Peirce (1930) defined
the bending length c = (B / w)^(1/3) = L lambda^(-1/3) and approximated the
elastica by

    c = L (cos(phi/2) / (8 tan phi))^(1/3),   phi the angle of the clamp-to-tip
    chord below the horizontal.

ASTM D1388 slides the strip out until its chord reaches phi = 41.5 deg and takes
c = L/2. The exact elastica has its chord at 41.5 deg for lambda = 8.004, c = 0.49991
L: the standard's c = L/2 is exact to 0.02 %. Peirce's formula gives 0.5093 L there,
1.9 % high in c (5.7 % in B = w c^3): it is good at small angles and drifts as the
strip bends, +0.03 % in c at a 5 deg chord, +0.1 % at 10, +0.4 % at 20, +1.0 % at
30, +2.2 % at 45, +4.4 % at 60 (peirce_error(); `python3 scripts/elastica.py`
prints the table).

Large lambda: shooting from the tip. Past lambda of a few hundred the strip hangs
nearly vertical over most of its length and theta' there is exponentially small, so
the shot from the clamp loses it to round-off (solve() stops converging near
lambda = 500). solve_tip() shoots the other way: with tau = 1 - sigma and
phi = pi/2 - theta (the angle from the vertical),

    phi''(tau) = lambda tau sin phi,   phi(0) = phi_tip,  phi'(0) = 0,

and the clamp asks phi(1) = pi/2. phi'' > 0 while 0 < phi < pi, so phi rises from
the tip; a larger phi_tip stays larger as long as both are below pi/2, so phi(1) -
pi/2 changes sign once, at the hanging solution, as phi_tip goes from 0 to pi/2. The
root is bracketed on log phi_tip (phi_tip ~ exp(-(2/3) lambda^(1/2)) when the strip
hangs: 1e-29 at lambda = 1e4) and the near-vertical part is integrated in the
direction in which it grows, so nothing is lost to round-off. The limp limit is a
known answer: the strip hangs straight down below a bend at the clamp, where the whole
weight w L pulls, of length (B / (w L))^(1/2) = L lambda^(-1/2); the tensioned elastica
turning through 90 degrees there, B theta'^2 / 2 = w L (1 - sin theta), sets the tip
off by int cos theta ds = (2 B / (w L))^(1/2): reach / L -> (2 / lambda)^(1/2)
(0.8 % below the exact reach at lambda = 1e4, 0.3 % at 1e5), and the bend's arc
exceeds its drop by int (1 - sin theta) ds = (2 - 2^(1/2)) L lambda^(-1/2), so
drop / L -> 1 - (2 - 2^(1/2)) lambda^(-1/2). It agrees with
solve() where both converge (tests/test_cusick_fabrics.py) and reaches lambda ~ 1e6
(phi_tip must stay above the smallest double).

Usage:
    python3 scripts/elastica.py                 # a table: lambda, drop, reach, chord, Peirce's error
    import elastica; elastica.solve(8.0)        # Elastica(lam, slope0, drop, reach, ...)
    elastica.solve_tip(1e4)                     # the same, shot from the tip (any lambda up to ~1e6)
"""
import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Elastica:
    """Rest shape of a heavy cantilever of unit free length (multiply lengths by L)."""

    lam: float  # w L^3 / B
    slope0: float  # L theta'(0): the clamp moment over B / L
    drop: float  # tip drop / L
    reach: float  # tip reach / L
    tip_angle: float  # theta(1), rad
    sigma: np.ndarray  # s / L on the grid
    theta: np.ndarray  # theta on the grid
    x: np.ndarray  # reach / L on the grid
    y: np.ndarray  # drop / L on the grid

    @property
    def chord_angle(self):
        """Angle of the clamp-to-tip chord below the horizontal (rad)."""
        return math.atan2(self.drop, self.reach)


def _rk4(f, s, y, h):
    """One classical Runge-Kutta step of y' = f(s, *y) from s."""
    k1 = f(s, *y)
    k2 = f(s + h / 2, *(v + h / 2 * k for v, k in zip(y, k1)))
    k3 = f(s + h / 2, *(v + h / 2 * k for v, k in zip(y, k2)))
    k4 = f(s + h, *(v + h * k for v, k in zip(y, k3)))
    return tuple(v + h / 6 * (a + 2 * b + 2 * c + d) for v, a, b, c, d in zip(y, k1, k2, k3, k4))


def _shoot(lam, p, n, keep=False):
    """RK4 from sigma = 0 with theta'(0) = p: theta'(1), d theta'(1)/dp and the end state
    (theta, theta', x, y), with the path on the grid if `keep`.

    On the hanging solution theta' >= 0 throughout (theta' B is the moment of the
    weight beyond s). A shot whose theta' turns negative before the tip started too
    low (at large lambda it would curl up and over, onto another, unstable, root);
    it returns a negative residual, -1 - (1 - sigma) at the turn, and no slope."""
    h = 1.0 / n
    cos, sin = math.cos, math.sin

    def f(s, th, om, x, y, dth, dom):
        a = lam * (1 - s)
        c, si = cos(th), sin(th)
        return om, -a * c, c, si, dom, a * si * dth

    th, om, x, y, dth, dom = 0.0, p, 0.0, 0.0, 0.0, 1.0
    path = [(th, om, x, y)] if keep else None
    for k in range(n):
        th, om, x, y, dth, dom = _rk4(f, k * h, (th, om, x, y, dth, dom), h)
        if om < 0 and k + 1 < n:
            return -1.0 - (1 - (k + 1) * h), 0.0, (th, om, x, y), path
        if keep:
            path.append((th, om, x, y))
    return om, dom, (th, om, x, y), path


def solve(lam, n=1000, tol=1e-12):
    """Heavy elastica for lambda = w L^3 / B > 0 (drop and reach per unit free length).

    Safeguarded Newton on p = theta'(0) in [0, lambda/2]: every other step, and any
    Newton step that would leave the bracket, is a bisection."""
    if not lam > 0:
        raise ValueError(f"lambda = w L^3 / B must be positive, not {lam}")
    lo, hi = 0.0, lam / 2
    p = min(lam / 2, max(0.0, lam / 2 - lam ** 3 / 320))  # the small-deflection expansion
    for k in range(200):
        r, dr, _, _ = _shoot(lam, p, n)
        if abs(r) <= tol * max(1.0, lam):
            break
        if r < 0:
            lo = p
        else:
            hi = p
        q = p - r / dr if dr > 0 else None
        p = q if k % 2 == 0 and q is not None and lo < q < hi else (lo + hi) / 2
    else:
        raise RuntimeError(f"the shooting for lambda = {lam} did not converge (residual {r:.3e})")
    _, _, _, path = _shoot(lam, p, n, keep=True)
    path = np.array(path)
    return Elastica(lam, p, path[-1, 3], path[-1, 2], path[-1, 0], np.linspace(0.0, 1.0, n + 1), path[:, 0], path[:, 2], path[:, 3])


def _shoot_tip(lam, phi_tip, n, keep=False):
    """RK4 from the tip (tau = 1 - sigma = 0) with phi = pi/2 - theta = phi_tip, phi' = 0:
    phi''(tau) = lam tau sin phi, and the reach X and drop Y accumulated from the tip.
    Returns phi(1) - pi/2 and, if `keep`, the path [(phi, phi', X, Y)] on the tau grid."""
    h = 1.0 / n
    sin, cos = math.sin, math.cos

    def f(t, ph, om, X, Y):
        return om, lam * t * sin(ph), sin(ph), cos(ph)

    ph, om, X, Y = phi_tip, 0.0, 0.0, 0.0
    path = [(ph, om, X, Y)] if keep else None
    for k in range(n):
        ph, om, X, Y = _rk4(f, k * h, (ph, om, X, Y), h)
        if ph > math.pi:  # far past the clamp's angle: the residual's sign is known
            return ph - math.pi / 2, path
        if keep:
            path.append((ph, om, X, Y))
    return ph - math.pi / 2, path


def _illinois(f, a, b, fa, fb, done, maxit, failure):
    """Root of the increasing f on [a, b] (fa < 0 < fb) by regula falsi with the Illinois
    modification; stops when done(f(x), a, b, x) holds, raises RuntimeError(failure) after
    maxit steps."""
    side = 0
    for _ in range(maxit):
        x = (a * fb - b * fa) / (fb - fa)
        fx = f(x)
        if done(fx, a, b, x):
            return x
        if fx < 0:
            a, fa = x, fx
            if side == -1:
                fb /= 2
            side = -1
        else:
            b, fb = x, fx
            if side == 1:
                fa /= 2
            side = 1
    raise RuntimeError(failure)


def solve_tip(lam, n=None, tol=1e-13):
    """Heavy elastica for lambda = w L^3 / B > 0, shot from the free end (see the docstring):
    the same Elastica as solve(), for any lambda up to about 1e6.

    Regula falsi (Illinois) on u = log phi_tip, phi_tip = pi/2 - theta(1), bracketed by
    [log 1e-300, log pi/2]. The grid, n steps (default max(1000, 20 sqrt(lambda))), resolves
    the clamp's boundary layer, of width lambda^(-1/2)."""
    if not lam > 0:
        raise ValueError(f"lambda = w L^3 / B must be positive, not {lam}")
    n = n or max(1000, int(20 * math.sqrt(lam)))
    a, b = math.log(1e-300), math.log(math.pi / 2)
    fa, fb = _shoot_tip(lam, math.exp(a), n)[0], _shoot_tip(lam, math.exp(b), n)[0]
    if fa >= 0:
        raise ValueError(f"lambda = {lam} is too large for solve_tip: the tip's angle to the vertical is below 1e-300")
    if fb <= 0:  # lambda so small that the tip is horizontal to round-off
        u = b
    else:
        u = _illinois(lambda v: _shoot_tip(lam, math.exp(v), n)[0], a, b, fa, fb, lambda fv, lo, hi, v: abs(fv) < tol or hi - lo < 1e-15 * max(1.0, abs(v)), 400,
                      f"the shooting from the tip for lambda = {lam} did not converge")
    _, path = _shoot_tip(lam, math.exp(u), n, keep=True)
    path = np.array(path)[::-1]  # on sigma = 1 - tau, from the clamp
    phi, om, X, Y = path.T
    theta = math.pi / 2 - phi
    x, y = X[0] - X, Y[0] - Y
    return Elastica(lam, float(om[0]), float(y[-1]), float(x[-1]), float(theta[-1]), np.linspace(0.0, 1.0, n + 1), theta, x, y)


def _shoot_frictional(lam, p, n, keep=False):
    """RK4 from the clamp with theta'(0) = p until theta' falls to 0 (the moment has
    dropped to the friction's) or the tip: sigma* and (theta, x, y) there, and the path
    [(sigma, theta, x, y)] if `keep`."""
    h = 1.0 / n
    cos, sin = math.cos, math.sin

    def f(s, th, om, x, y):
        return om, -lam * (1 - s) * cos(th), cos(th), sin(th)

    th, om, x, y = 0.0, p, 0.0, 0.0
    path = [(0.0, th, x, y)] if keep else None
    for k in range(n):
        s = k * h
        nth, nom, nx, ny = _rk4(f, s, (th, om, x, y), h)
        if nom <= 0:  # theta' reaches 0 inside this step: stop there (linear in theta')
            t = om / (om - nom)
            th, x, y = th + t * (nth - th), x + t * (nx - x), y + t * (ny - y)
            if keep:
                path.append((s + t * h, th, x, y))
            return s + t * h, th, x, y, path
        th, om, x, y = nth, nom, nx, ny
        if keep:
            path.append((s + h, th, x, y))
    return 1.0, th, x, y, path


def solve_frictional(lam, eta, n=4000, tol=1e-12):
    """Heavy cantilever with Grosberg's elastic-frictional bending law, loaded once from flat.

    A fabric's bending moment on first loading is M = HB + B kappa once M exceeds the
    friction moment HB between its yarns (KES-FB2 measures 2 HB, the width of the
    moment-curvature loop, and B, its slope), and the fabric does not bend where M <=
    HB (Grosberg 1966; Lahey and Heppler 2004). The weight's moment about the point at s
    falls towards the tip, so the strip bends from the clamp to sigma* where it has
    fallen to HB, and beyond sigma* it is a straight rigid tail at the angle theta*.
    On [0, sigma*] B theta' = M - HB with M' the same as the elastica's, so

        theta'' = -lambda (1 - sigma) cos theta,  theta(0) = 0,  theta'(sigma*) = 0,

    and the tail's weight moment at sigma* is the friction's:
    lambda (1 - sigma*)^2 cos theta* / 2 = eta, with eta = HB L / B. Shooting on p =
    theta'(0) by bisection on [0, lambda/2]: a larger p bends longer, so sigma* grows
    and the tail's moment falls. eta = 0 is the elastica (sigma* = 1); eta >= lambda/2
    (the flat strip's clamp moment) leaves the strip flat. The drop and reach on the
    first loading are what a Cusick specimen falling from flat reaches, not a shape
    the fabric returns to (the law is hysteretic)."""
    if not lam > 0 or not eta >= 0:
        raise ValueError(f"lambda = w L^3 / B must be positive and eta = HB L / B non-negative, not {lam}, {eta}")

    def residual(p):
        sstar, th, _, _, _ = _shoot_frictional(lam, p, n)
        return lam * (1 - sstar) ** 2 * math.cos(th) / 2 - eta

    if residual(0.0) <= 0:  # the friction holds the whole strip flat
        sig = np.linspace(0.0, 1.0, n + 1)
        return Elastica(lam, 0.0, 0.0, 1.0, 0.0, sig, np.zeros_like(sig), sig, np.zeros_like(sig))
    lo, hi = 0.0, lam / 2
    while hi - lo > tol * max(1.0, lam):
        mid = (lo + hi) / 2
        if residual(mid) > 0:
            lo = mid
        else:
            hi = mid
    sstar, th, x, y, path = _shoot_frictional(lam, hi, n, keep=True)
    path = np.array(path)
    tail = np.linspace(sstar, 1.0, max(2, int(round((1 - sstar) * n)) + 1))[1:]
    sigma = np.concatenate([path[:, 0], tail])
    theta = np.concatenate([path[:, 1], np.full(len(tail), th)])
    xs = np.concatenate([path[:, 2], x + (tail - sstar) * math.cos(th)])
    ys = np.concatenate([path[:, 3], y + (tail - sstar) * math.sin(th)])
    return Elastica(lam, hi, float(ys[-1]), float(xs[-1]), th, sigma, theta, xs, ys)


def grosberg_law(eta, ratio=math.inf):
    """Curvature L theta' of the strip's first loading at the moment m = M L / B under
    Grosberg's elastic-frictional law regularised as drape's -cloth_bend_hysteresis:
    beside the elastic bending B, a spring of stiffness K = ratio B in series with a
    slider that carries at most HB (eta = HB L / B). Until the spring carries HB the
    section bends with B + K, m / (1 + ratio); beyond, the slider slides and the
    elastic part alone takes the rest, m - eta. ratio = inf is Grosberg's rigid-plastic
    friction (no bending where m <= eta: solve_frictional)."""
    if not eta >= 0 or not ratio > 0:
        raise ValueError(f"eta = HB L / B must be non-negative and the stick ratio K / B positive, not {eta}, {ratio}")
    m_yield = eta * (1 + 1 / ratio)

    def curvature(m):
        return m / (1 + ratio) if m <= m_yield else m - eta
    return curvature


def solve_law(lam, curvature, n=4000, tol=1e-12):
    """Heavy cantilever whose section bends with L theta' = curvature(m) under the
    moment m = M L / B (a first-loading law, monotone, curvature(0) = 0).

    The moment at s balances the weight beyond it, so m' = -lambda (1 - sigma) cos theta
    (differentiating B theta' = w int_s^L (x(t) - x(s)) dt as in the module docstring),
    with theta(0) = 0 at the clamp and m(1) = 0 at the free end. Shooting on m(0) by
    bisection on [0, lambda/2] (the flat strip's clamp moment bounds it: cos theta <= 1),
    RK4 for (theta, m, x, y). curvature = identity is the elastica (solve());
    grosberg_law(eta) is solve_frictional()'s law. A kink in the law (the slider's
    yield) makes RK4 second order there: n = 4000 gives the tip to about 1e-7."""
    if not lam > 0:
        raise ValueError(f"lambda = w L^3 / B must be positive, not {lam}")
    h = 1.0 / n
    cos, sin = math.cos, math.sin

    def f(s, th, m, x, y):
        return curvature(m), -lam * (1 - s) * cos(th), cos(th), sin(th)

    def shoot(m0, keep=False):
        st = (0.0, m0, 0.0, 0.0)
        path = [st] if keep else None
        for k in range(n):
            st = _rk4(f, k * h, st, h)
            if keep:
                path.append(st)
        return st, path

    lo, hi = 0.0, lam / 2
    while hi - lo > tol * max(1.0, lam):
        mid = (lo + hi) / 2
        if shoot(mid)[0][1] < 0:
            lo = mid
        else:
            hi = mid
    (th, _, x, y), path = shoot(hi, keep=True)
    path = np.array(path)
    return Elastica(lam, hi, y, x, th, np.linspace(0.0, 1.0, n + 1), path[:, 0], path[:, 2], path[:, 3])


def lam_for(value, of="drop", lo=1e-3, hi=100.0, n=1000, tol=1e-10):
    """lambda at which the elastica's `of` ("drop" per L or "chord" angle in rad) equals `value`.

    Both grow with lambda; the answer is found by regula falsi (Illinois) on log lambda."""
    get = (lambda e: e.drop) if of == "drop" else (lambda e: e.chord_angle)
    a, b = math.log(lo), math.log(hi)
    fa, fb = get(solve(lo, n)) - value, get(solve(hi, n)) - value
    if not fa < 0 < fb:
        raise ValueError(f"{of} = {value} is outside the range of lambda in [{lo}, {hi}]")
    return math.exp(_illinois(lambda v: get(solve(math.exp(v), n)) - value, a, b, fa, fb, lambda fv, lo, hi, v: abs(fv) < tol or hi - lo < tol, 100,
                              f"no lambda found for {of} = {value}"))


def peirce_ratio(phi):
    """Peirce's c / L for a chord angle phi (rad): (cos(phi/2) / (8 tan phi))^(1/3)."""
    return (math.cos(phi / 2) / (8 * math.tan(phi))) ** (1 / 3)


def peirce_error(phi, n=1000):
    """Relative error of Peirce's bending length against the elastica's, at chord angle phi (rad)."""
    exact = lam_for(phi, "chord", n=n) ** (-1 / 3)
    return peirce_ratio(phi) / exact - 1


def main():
    print(" lambda   drop/L   reach/L  chord deg   c/L exact  c/L Peirce  Peirce error in c (in B)")
    for lam in (0.5, 1, 2, 5, 8, 10, 20, 50):
        e = solve(lam)
        phi = e.chord_angle
        exact = lam ** (-1 / 3)
        err = peirce_ratio(phi) / exact - 1
        print(f"{lam:7.2f}  {e.drop:7.4f}  {e.reach:7.4f}  {math.degrees(phi):8.3f}  {exact:10.5f}  {peirce_ratio(phi):10.5f}"
              f"  {100 * err:+6.3f} % ({100 * ((1 + err) ** 3 - 1):+6.3f} %)")


if __name__ == "__main__":
    main()
