#!/usr/bin/env python3
"""Beam-theory reference values for the cantilever and beam_modes regression cases.

Beam: L = 1 m along x, rectangular section h = 0.05 m (along y) x b = 0.1 m (along z),
steel E = 2.1e11 Pa, nu = 0.3, rho = 7850 kg/m^3, G = E / (2 (1 + nu)).

Every quantity is computed by two independent methods and the script asserts that they agree:

  tip deflection (tip force P = 1 MPa * h * b = 5 kN in -y)
      closed form P L^3/(3EI) [+ P L/(kappa G A)]  <->  static FE solve (Timoshenko elements)
  Euler-Bernoulli frequencies
      roots of 1 + cos cosh = 0 / cos cosh = 1    <->  Hermite FE + Richardson extrapolation
  Timoshenko frequencies (shear deformation + rotary inertia)
      roots of the exact 4x4 boundary-condition determinant  <->  FE + Richardson extrapolation
  Saint-Venant torsion constant J
      series over odd n                            <->  finite-difference Prandtl stress function
  torsional / axial rod frequencies
      f = (1/4L) sqrt(stiffness/inertia) etc.      <->  linear rod FE + Richardson extrapolation

Shear correction factor: Cowper's kappa = 10 (1 + nu) / (12 + 11 nu) (primary) and 5/6.

Usage:  python3 scripts/reference/beam_theory.py [--yaml]
(needs numpy and scipy, e.g. Debian's python3-numpy python3-scipy)
"""
import argparse
import math
import sys

try:
    import numpy as np
    from scipy.linalg import eigh
    from scipy.optimize import brentq
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
except ImportError as exc:  # pragma: no cover
    sys.exit(f"beam_theory.py needs numpy and scipy ({exc}); "
             "e.g. apt-get install python3-numpy python3-scipy and run /usr/bin/python3")

# ----------------------------------------------------------------------------- data
L = 1.0          # m
H = 0.05         # m, section size along y
B = 0.1          # m, section size along z
E = 2.1e11       # Pa
NU = 0.3
RHO = 7850.0     # kg/m^3
G = E / (2.0 * (1.0 + NU))
A = H * B
TRACTION = 1.0e6           # Pa, tip shear traction of cases/cantilever
P = TRACTION * A           # N, = 5000 N in -y

KAPPAS = {  # name -> value; the first one is the primary value
    "cowper": 10.0 * (1.0 + NU) / (12.0 + 11.0 * NU),
    "5/6": 5.0 / 6.0,
}
PRIMARY = "cowper"

# bending direction -> second moment of area
SECTIONS = {
    "y": B * H**3 / 12.0,   # bending in y: about z
    "z": H * B**3 / 12.0,   # bending in z: about y
}

N_MODES = 3
N_ORDER = 6                # bending modes per direction used for the mode ordering
F_ORDER = 1000.0           # Hz, ordering printed below this frequency
MESHES = (50, 100, 200, 400)
TOL_FREQ = 1e-6            # required relative agreement of the two Timoshenko methods
TWO_PI = 2.0 * math.pi


def rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


# ----------------------------------------------------------------------------- root finding
def scan_roots(func, x_lo, x_hi, n_roots, n_steps):
    """First n_roots sign changes of func on (x_lo, x_hi], refined with brentq."""
    xs = np.linspace(x_lo, x_hi, n_steps + 1)
    roots = []
    f_prev = func(xs[0])
    for x0, x1 in zip(xs[:-1], xs[1:]):
        f1 = func(x1)
        if f_prev == 0.0:
            roots.append(x0)
        elif f_prev * f1 < 0.0:
            roots.append(brentq(func, x0, x1, xtol=1e-14, rtol=1e-15, maxiter=200))
        if len(roots) == n_roots:
            return roots
        f_prev = f1
    raise RuntimeError(f"only {len(roots)} of {n_roots} roots found below {x_hi}")


def eb_char_roots(kind, n):
    """beta*L roots: clamped-free 1 + cos x cosh x = 0, free-free cos x cosh x = 1 (x > 0).

    Written as cos x + 1/cosh x (resp. cos x - 1/cosh x) = 0 to avoid the cosh overflow
    and to keep the function O(1)."""
    if kind == "clamped-free":
        f = lambda x: math.cos(x) + 1.0 / math.cosh(x)
    else:
        f = lambda x: math.cos(x) - 1.0 / math.cosh(x)
    # start past the double root x = 0 of the free-free equation
    return scan_roots(f, 0.5, (n + 1.5) * math.pi, n, 4000)


# ----------------------------------------------------------------------------- exact Timoshenko
class Timoshenko:
    """Timoshenko beam, harmonic motion at angular frequency om:
        kGA (w'' - psi') + rho A om^2 w = 0,
        EI psi'' + kGA (w' - psi) + rho I om^2 psi = 0,
    w: deflection, psi: rotation of the section, moment M = EI psi', shear V = kGA (w' - psi)."""

    def __init__(self, I, kappa, area=A):
        self.EI = E * I
        self.kGA = kappa * G * area
        self.rA = RHO * area
        self.rI = RHO * I

    def cutoff(self):
        """omega_c = sqrt(kGA / (rho I)): above it the second pair of roots turns oscillatory."""
        return math.sqrt(self.kGA / self.rI)

    def char_q(self, om):
        """Roots q = s^2 of the characteristic polynomial for w, psi ~ exp(s x):
        kGA EI q^2 + om^2 (kGA rho I + rho A EI) q + rho A om^2 (rho I om^2 - kGA) = 0.
        The product of the roots has the sign of (om - omega_c): below the cut-off
        q1 > 0 > q2 (cosh/sinh + cos/sin), above it q1, q2 < 0 (two cos/sin pairs).
        The discriminant is always > 0, so the roots are real and distinct."""
        a = self.kGA * self.EI
        b = om**2 * (self.kGA * self.rI + self.rA * self.EI)
        c = self.rA * om**2 * (self.rI * om**2 - self.kGA)
        disc = math.sqrt(b * b - 4.0 * a * c)
        q2 = (-b - disc) / (2.0 * a)   # always < 0 (b > 0 for om > 0)
        q1 = c / (a * q2)              # = (-b + disc)/(2a) without cancellation
        return q1, q2

    @staticmethod
    def cs(q, x):
        """C = cosh(sqrt(q) x), S = sinh(sqrt(q) x)/sqrt(q), analytic in q:
        q > 0: hyperbolic, q < 0: cos(k x), sin(k x)/k with k = sqrt(-q), q = 0: 1, x."""
        if q > 0.0:
            k = math.sqrt(q)
            return math.cosh(k * x), math.sinh(k * x) / k
        if q < 0.0:
            k = math.sqrt(-q)
            return math.cos(k * x), math.sin(k * x) / k
        return 1.0, x

    def basis(self, q, om, x):
        """Two real solutions belonging to the root q, as rows (w, psi, psi', w' - psi) at x.
        For exp(+-s x) the amplitude ratio is Psi/W = (kGA s^2 + rho A om^2)/(kGA s); with
        m = rho A om^2 / kGA and g = q + m the pair
            (1) w = C,     psi = g S,   w' - psi = -m S
            (2) w = q S,   psi = g C,   w' - psi = -m C
        solves the equations (C' = q S, S' = C) and stays independent and finite for every
        q, including q -> 0 at the cut-off, so one formula covers both regimes. The shear
        strain is written as -m S (-m C) instead of the difference w' - psi, which would
        cancel for slender beams (m << |q|)."""
        C, S = self.cs(q, x)
        m = self.rA * om**2 / self.kGA
        g = q + m
        return np.array([[C, g * S, g * C, -m * S],          # (w, psi, psi', gamma) of solution 1
                         [q * S, g * C, g * q * S, -m * C]])  # of solution 2

    def bc_rows(self, q1, q2, om, x, kind):
        """Two boundary-condition rows at x for the 4 coefficients."""
        cols = np.vstack([self.basis(q1, om, x), self.basis(q2, om, x)]).T  # 4 x 4: quantity x coeff
        w, psi, dpsi, gamma = cols
        if kind == "clamped":
            return [w, psi]
        # free: M = EI psi' = 0, V = kGA (w' - psi) = 0 (the constants EI, kGA dropped)
        return [dpsi, gamma]

    def det(self, om, bcs):
        q1, q2 = self.char_q(om)
        mat = np.array(self.bc_rows(q1, q2, om, 0.0, bcs[0]) + self.bc_rows(q1, q2, om, L, bcs[1]))
        return np.linalg.det(mat)

    def frequencies(self, bcs, n, om_hint):
        """First n roots omega > 0 of the BC determinant (rad/s), by a scan with step
        om_hint/200 (om_hint ~ first EB omega) and brentq on every sign change. The scan
        starts at om_hint/20, below the first elastic mode and past the rigid-body root
        om = 0 of the free-free beam."""
        f = lambda om: self.det(om, bcs)
        step = om_hint / 200.0
        lo = om_hint / 20.0
        f_lo = f(lo)
        roots = []
        while len(roots) < n:
            hi = lo + step
            f_hi = f(hi)
            if f_hi == 0.0:
                roots.append(hi)
            elif f_lo * f_hi < 0.0:
                roots.append(brentq(f, lo, hi, xtol=1e-14 * hi, rtol=1e-15, maxiter=200))
            lo, f_lo = hi, f_hi
            if lo > 1e4 * om_hint:
                raise RuntimeError("Timoshenko roots not found")
        return np.array(roots)


# ----------------------------------------------------------------------------- Timoshenko FE
def element_matrices(le, EI, kGA, rA, rI):
    """2-node Timoshenko element with interdependent interpolation (IIE), DOFs (w1, psi1, w2, psi2).

    The shape functions are the homogeneous static solution of the Timoshenko equations:
        w = a0 + a1 x + a2 x^2 + a3 x^3,  psi = a1 + 6 e a3 + 2 a2 x + 3 a3 x^2,  e = EI / kGA,
    so the stiffness is exact (nodally exact statics). kGA = inf (e = 0) gives the Hermite
    Euler-Bernoulli element. Consistent mass: rho A w^2 + rho I psi^2 (rI = 0: no rotary inertia).
    Returns K, M; K is checked against the closed-form IIE stiffness (phi = 12 e / le^2)."""
    e = 0.0 if math.isinf(kGA) else EI / kGA

    def wp(x):  # rows: w, w', psi, psi' as linear functions of (a0..a3)
        return np.array([[1.0, x, x * x, x**3],
                         [0.0, 1.0, 2 * x, 3 * x * x],
                         [0.0, 1.0, 2 * x, 3 * x * x + 6 * e],
                         [0.0, 0.0, 2.0, 6 * x]])

    T = np.array([wp(0.0)[0], wp(0.0)[2], wp(le)[0], wp(le)[2]])
    Tinv = np.linalg.inv(T)                      # a = Tinv @ dofs
    gp, gw = np.polynomial.legendre.leggauss(4)  # exact for the degree-6 integrands
    K = np.zeros((4, 4))
    M = np.zeros((4, 4))
    for xi, wgt in zip(gp, gw):
        x = 0.5 * le * (xi + 1.0)
        Nw, dNw, Np, dNp = wp(x) @ Tinv
        jw = 0.5 * le * wgt
        K += jw * EI * np.outer(dNp, dNp)
        if e > 0.0:
            gam = dNw - Np                      # = -6 e a3: constant shear strain
            K += jw * kGA * np.outer(gam, gam)
        M += jw * (rA * np.outer(Nw, Nw) + rI * np.outer(Np, Np))

    phi = 12.0 * e / le**2
    l = le
    K_cf = EI / ((1.0 + phi) * l**3) * np.array([
        [12.0, 6 * l, -12.0, 6 * l],
        [6 * l, (4 + phi) * l * l, -6 * l, (2 - phi) * l * l],
        [-12.0, -6 * l, 12.0, -6 * l],
        [6 * l, (2 - phi) * l * l, -6 * l, (4 + phi) * l * l]])
    assert np.allclose(K, K_cf, rtol=1e-10, atol=1e-10 * np.abs(K_cf).max()), "IIE stiffness"
    return K, M


def assemble(n_el, EI, kGA, rA, rI):
    """Global K, M (DOFs w_i, psi_i, node by node) and the 2x2 element stiffness K_d in
    the deformation coordinates (see strain_energy)."""
    le = L / n_el
    ke, me = element_matrices(le, EI, kGA, rA, rI)
    ndof = 2 * (n_el + 1)
    K = np.zeros((ndof, ndof))
    M = np.zeros((ndof, ndof))
    for i in range(n_el):
        s = slice(2 * i, 2 * i + 4)
        K[s, s] += ke
        M[s, s] += me
    # u_e = (0, -1, 0, 0) has (d1, d2) = (1, 0), u_e = (0, 0, 0, 1) has (0, 1)
    kd = np.array([[ke[1, 1], -ke[1, 3]], [-ke[3, 1], ke[3, 3]]])
    return K, M, kd


def strain_energy(u, kd, le):
    """2 x strain energy u^T K u, summed element by element from the deformation coordinates
    d1 = (w2 - w1)/le - psi1, d2 = psi2 - (w2 - w1)/le (zero for rigid-body motion).
    Unlike u^T K u with the assembled K, this has no cancellation between terms of size
    EI/le^3 |w|^2, so it stays accurate to ~1e-14 for fine meshes."""
    w, psi = u[0::2], u[1::2]
    chord = (w[1:] - w[:-1]) / le
    d1 = chord - psi[:-1]
    d2 = psi[1:] - chord
    return np.sum(kd[0, 0] * d1 * d1 + 2.0 * kd[0, 1] * d1 * d2 + kd[1, 1] * d2 * d2)


def fe_frequencies(n_el, EI, kGA, rA, rI, bcs, n):
    """First n elastic angular frequencies of the beam FE model (rad/s).

    Round-off: the spectrum of K u = lam M u spans ~ (n_el)^4, so eigh(K, M) loses
    ~ eps * lam_max / lam_1 (3e-4 relative for mode 1 with 400 elements). Hence the
    eigenvectors are taken from the inverted pencil M u = mu (K + sigma M) u (largest mu =
    lowest modes; sigma > 0 makes it definite for the free-free beam) and the eigenvalues
    from the Rayleigh quotient with the element-wise strain energy."""
    K, M, kd = assemble(n_el, EI, kGA, rA, rI)
    le = L / n_el
    if bcs == ("clamped", "free"):
        keep = np.arange(2, K.shape[0])
        n_rigid = 0
        sigma = 0.0
    else:
        keep = np.arange(K.shape[0])
        n_rigid = 2
        sigma = EI / (rA * L**4)    # < lam_1 (= 500 EI/(rho A L^4) for free-free)
    Kr, Mr = K[np.ix_(keep, keep)], M[np.ix_(keep, keep)]
    nd = len(keep)
    k = n_rigid + n
    mu, V = eigh(Mr, Kr + sigma * Mr, subset_by_index=[nd - k, nd - 1])
    order = np.argsort(-mu)
    mu, V = mu[order], V[:, order]
    lam_raw = 1.0 / mu - sigma
    if n_rigid:
        assert np.all(np.abs(lam_raw[:n_rigid]) < 1e-6 * lam_raw[n_rigid]), "rigid-body modes not ~0"
    lam = []
    for j in range(n_rigid, k):
        u = np.zeros(K.shape[0])
        u[keep] = V[:, j]
        lam.append(strain_energy(u, kd, le) / (V[:, j] @ Mr @ V[:, j]))
    lam = np.array(lam)
    assert np.all(np.abs(lam - lam_raw[n_rigid:]) < 1e-3 * lam), "Rayleigh quotient check"
    return np.sqrt(lam)


def richardson(values, orders):
    """Repeated Richardson extrapolation for meshes refined by 2: eliminates error terms
    h^p for p in orders, one per level (values: coarse to fine, len(orders) + 1 of them)."""
    v = [np.asarray(x, dtype=float) for x in values]
    for p in orders:
        v = [v[i + 1] + (v[i + 1] - v[i]) / (2.0**p - 1.0) for i in range(len(v) - 1)]
    assert len(v) == 1
    return v[0]


# Leading error terms of the FE frequencies: the Hermite (Euler-Bernoulli) element converges
# as h^4, h^6; the IIE Timoshenko element only as h^2, h^4 (its shear strain is constant per
# element); the linear rod element as h^2, h^4. The observed order is checked below.
ORDERS_EB = (4, 6)
ORDERS_TIMO = (2, 4)


def fe_converged(EI, kGA, rA, rI, bcs, n, meshes=MESHES, orders=ORDERS_TIMO):
    """FE frequencies on the meshes (each twice the previous), extrapolated from the three
    finest ones. Returns (extrapolated, error estimate = max rel. change of the last
    extrapolation level, observed order from the three coarsest meshes)."""
    vals = [fe_frequencies(m, EI, kGA, rA, rI, bcs, n) for m in meshes]
    d1 = np.abs(vals[1] - vals[0])
    d2 = np.abs(vals[2] - vals[1])
    order = np.log2(d1 / d2)
    assert np.all(np.abs(order - orders[0]) < 0.1), ("unexpected FE convergence order", order)
    best = richardson(vals[-3:], orders)
    one = richardson(vals[-2:], orders[:1])
    return best, np.max(np.abs(best - one) / best), np.min(order)


# ----------------------------------------------------------------------------- statics
def tip_deflection_fe(I, kappa, n_el=10):
    """u_y at the tip by a static FE solve (IIE elements are nodally exact)."""
    kGA = math.inf if kappa is None else kappa * G * A
    K, _, _ = assemble(n_el, E * I, kGA, RHO * A, 0.0)
    f = np.zeros(K.shape[0])
    f[-2] = -P
    u = np.linalg.solve(K[2:, 2:], f[2:])
    return u[-2]


# ----------------------------------------------------------------------------- torsion / axial
def torsion_J_series(a, t, tol=1e-16):
    """Saint-Venant J of an a x t rectangle (a >= t):
    J = a t^3 / 3 [1 - 192 t / (pi^5 a) sum_{n odd} tanh(n pi a / (2 t)) / n^5]."""
    a, t = max(a, t), min(a, t)
    s = 0.0
    n = 1
    while True:
        term = math.tanh(n * math.pi * a / (2.0 * t)) / n**5
        s += term
        if term < tol * s:
            break
        n += 2
    return a * t**3 / 3.0 * (1.0 - 192.0 * t / (math.pi**5 * a) * s), n


def torsion_J_fd(a, t, n_short):
    """J = 2 * integral of the Prandtl stress function, laplace(phi) = -2, phi = 0 on the
    boundary, 5-point finite differences with n_short intervals along the short side."""
    n_long = int(round(n_short * a / t))
    hx, hy = a / n_long, t / n_short
    nx, ny = n_long - 1, n_short - 1
    Dx = sp.diags([np.ones(nx - 1), -2 * np.ones(nx), np.ones(nx - 1)], [-1, 0, 1]) / hx**2
    Dy = sp.diags([np.ones(ny - 1), -2 * np.ones(ny), np.ones(ny - 1)], [-1, 0, 1]) / hy**2
    lap = sp.kron(sp.identity(ny), Dx) + sp.kron(Dy, sp.identity(nx))
    phi = spla.spsolve(lap.tocsc(), -2.0 * np.ones(nx * ny))
    return 2.0 * phi.sum() * hx * hy


def rod_fe_frequency(n_el, stiff, inertia, bcs):
    """First nonzero frequency (rad/s) of a rod: linear elements, consistent mass."""
    le = L / n_el
    n = n_el + 1
    main = np.full(n, 2.0)
    main[0] = main[-1] = 1.0
    K = (np.diag(main) - np.diag(np.ones(n - 1), 1) - np.diag(np.ones(n - 1), -1)) * stiff / le
    M = (np.diag(2 * main) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)) * inertia * le / 6
    if bcs == "clamped-free":
        K, M = K[1:, 1:], M[1:, 1:]
        lam = eigh(K, M, eigvals_only=True, subset_by_index=[0, 0])[0]
    else:
        lam0, lam = eigh(K, M, eigvals_only=True, subset_by_index=[0, 1])
        assert abs(lam0) < 1e-8 * lam
    return math.sqrt(lam)


def rod_frequency(stiff, inertia, bcs):
    """(closed form Hz, FE+Richardson Hz) of the first rod mode; clamped-free 1/(4L), free-free 1/(2L)."""
    c = math.sqrt(stiff / inertia)
    exact = c / (4.0 * L) if bcs == "clamped-free" else c / (2.0 * L)
    vals = [rod_fe_frequency(m, stiff, inertia, bcs) / TWO_PI for m in (100, 200, 400)]
    return exact, float(richardson(vals, (2, 4)))


# ----------------------------------------------------------------------------- self-test
def selftest_above_cutoff():
    """Deep beam (L/h = 2, y-bending, Cowper): several clamped-free and free-free modes lie
    above omega_c, exercising the oscillatory-oscillatory regime of the exact determinant;
    compared with the FE model. Returns (n modes above cut-off, max relative difference)."""
    h = 0.5
    I = B * h**3 / 12.0
    area = B * h
    kappa = KAPPAS[PRIMARY]
    tb = Timoshenko(I, kappa, area)
    om_c = tb.cutoff()
    n_above = 0
    worst = 0.0
    for bcs in (("clamped", "free"), ("free", "free")):
        om_eb1 = 3.5 * math.sqrt(E * I / (RHO * area * L**4))
        exact = tb.frequencies(bcs, 8, om_eb1)
        fe, _, _ = fe_converged(E * I, tb.kGA, RHO * area, RHO * I, bcs, 8, meshes=(100, 200, 400))
        worst = max(worst, np.max(np.abs(exact - fe) / exact))
        n_above += int(np.sum(exact > om_c))
    return n_above, worst


# ----------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--yaml", action="store_true", help="print a YAML snippet of the values (7 significant digits)")
    args = ap.parse_args()

    out = []  # printed report lines
    say = out.append
    res = {}  # values for YAML

    # --- section properties
    Iy, Iz = SECTIONS["y"], SECTIONS["z"]
    J, n_terms = torsion_J_series(B, H)
    J_fd = {n: torsion_J_fd(B, H, n) for n in (40, 80, 160)}
    J_fd_r = J_fd[160] + (J_fd[160] - J_fd[80]) / 3.0      # Richardson, O(h^2)
    assert rel(J, J_fd_r) < 1e-6, (J, J_fd_r)
    Ip = B * H * (B**2 + H**2) / 12.0

    say("Beam L = %g m, h = %g m (y), b = %g m (z), E = %g Pa, nu = %g, rho = %g kg/m^3, G = %.7g Pa"
        % (L, H, B, E, NU, RHO, G))
    say("A = %.7g m^2, I (y-bending, b h^3/12) = %.7g m^4, I (z-bending, h b^3/12) = %.7g m^4"
        % (A, Iy, Iz))
    say("kappa: Cowper 10(1+nu)/(12+11nu) = %.7f (primary), 5/6 = %.7f" % (KAPPAS["cowper"], KAPPAS["5/6"]))
    say("Saint-Venant J = %.7g m^4 (series, %d odd terms); FD Prandtl stress function + Richardson "
        "%.7g (rel. diff %.1e); I_p = %.7g m^4" % (J, (n_terms + 1) // 2, J_fd_r, rel(J, J_fd_r), Ip))
    res["section"] = {"A": A, "I_y_bending": Iy, "I_z_bending": Iz, "J": J, "I_p": Ip}
    res["kappa"] = dict(KAPPAS)

    # --- 1. cantilever tip deflection
    say("")
    say("1. Cantilever, tip force P = %g N in -y: tip u_y [m]" % P)
    say("   %-26s %15s %15s %10s" % ("model", "closed form", "FE (static)", "rel.diff"))
    d_eb = -P * L**3 / (3 * E * Iy)
    d_eb_fe = tip_deflection_fe(Iy, None)
    assert rel(d_eb, d_eb_fe) < 1e-10
    say("   %-26s %15.7e %15.7e %10.1e" % ("Euler-Bernoulli", d_eb, d_eb_fe, rel(d_eb, d_eb_fe)))
    res["tip_uy"] = {"euler_bernoulli": d_eb}
    for name, kappa in KAPPAS.items():
        d_t = d_eb - P * L / (kappa * G * A)
        d_t_fe = tip_deflection_fe(Iy, kappa)
        assert rel(d_t, d_t_fe) < 1e-10
        say("   %-26s %15.7e %15.7e %10.1e" % ("Timoshenko kappa=" + name, d_t, d_t_fe, rel(d_t, d_t_fe)))
        res["tip_uy"]["timoshenko_" + name] = d_t
    say("   (shear part P L/(kappa G A) = %.4e m = %.2f %% of the bending part, Cowper)"
        % (P * L / (KAPPAS[PRIMARY] * G * A), 100 * P * L / (KAPPAS[PRIMARY] * G * A) / abs(d_eb)))

    # --- 2. bending frequencies
    worst_timo = 0.0
    freqs = {}  # (bcs, dir) -> dict(model -> array Hz)
    bc_sets = {"clamped-free": ("clamped", "free"), "free-free": ("free", "free")}
    say("")
    say("2. Bending natural frequencies [Hz] (free-free: the 2 rigid-body modes per direction are 0 Hz,"
        " checked in the FE model, and omitted)")
    for bc_name, bcs in bc_sets.items():
        bl = np.array(eb_char_roots(bc_name, N_MODES))
        for d in ("y", "z"):
            I = SECTIONS[d]
            scale = math.sqrt(E * I / (RHO * A * L**4))
            eb = bl**2 * scale / TWO_PI
            eb_fe, eb_err, eb_ord = fe_converged(E * I, math.inf, RHO * A, 0.0, bcs, N_MODES, orders=ORDERS_EB)
            eb_fe /= TWO_PI
            assert np.all(np.abs(eb - eb_fe) / eb < TOL_FREQ), (eb, eb_fe)
            entry = {"beta_L": bl, "euler_bernoulli": eb, "eb_fe": eb_fe}
            say("")
            say("   %s, bending in %s (I = %.5g m^4), beta*L = %s"
                % (bc_name, d, I, ", ".join("%.9f" % x for x in bl)))
            say("   %-22s %14s %14s %14s   %s" % ("model", "mode 1", "mode 2", "mode 3", "check"))
            say("   %-22s %14.7f %14.7f %14.7f   vs Hermite FE + Richardson h^4,h^6: max rel.diff %.1e "
                "(observed order %.2f)" % ("Euler-Bernoulli", *eb, np.max(np.abs(eb - eb_fe) / eb), eb_ord))
            for name, kappa in KAPPAS.items():
                tb = Timoshenko(I, kappa)
                om_c = tb.cutoff()
                ex = tb.frequencies(bcs, N_MODES, bl[0]**2 * scale)
                assert np.all(ex < om_c), "mode above the Timoshenko cut-off"
                fe, fe_err, fe_ord = fe_converged(E * I, tb.kGA, tb.rA, tb.rI, bcs, N_MODES)
                diff = np.max(np.abs(ex - fe) / ex)
                assert diff < TOL_FREQ, (bc_name, d, name, ex, fe)
                worst_timo = max(worst_timo, diff)
                entry["timoshenko_" + name] = ex / TWO_PI
                entry["fe_" + name] = fe / TWO_PI
                entry["cutoff_" + name] = om_c / TWO_PI
                say("   %-22s %14.7f %14.7f %14.7f   exact det vs FE+Richardson max rel.diff %.1e"
                    % ("Timoshenko k=" + name, *(ex / TWO_PI), diff))
                say("   %-22s %14.7f %14.7f %14.7f   (FE 100/200/400 el. + Richardson h^2,h^4; est. err %.0e; "
                    "observed order %.2f)" % ("  FE", *(fe / TWO_PI), fe_err, fe_ord))
                if name == PRIMARY:
                    # more modes (exact method only) for the mode ordering below
                    more = tb.frequencies(bcs, N_ORDER, bl[0]**2 * scale)
                    assert np.allclose(more[:N_MODES], ex, rtol=1e-12)
                    entry["ordering"] = more / TWO_PI
            say("   cut-off f_c = sqrt(kGA/(rho I))/2pi = %.1f Hz (Cowper): all modes below it "
                "(one hyperbolic + one trigonometric root pair)" % entry["cutoff_" + PRIMARY])
            freqs[(bc_name, d)] = entry

    # --- 3. torsion and axial (information)
    say("")
    say("3. Rod modes (Saint-Venant torsion without warping restraint; axial) [Hz]")
    say("   %-26s %15s %15s %10s" % ("mode", "closed form", "FE+Richardson", "rel.diff"))
    rods = {}
    for bc_name in bc_sets:
        for what, stiff, inertia in (("torsion", G * J, RHO * Ip), ("axial", E * A, RHO * A)):
            ex, fe = rod_frequency(stiff, inertia, bc_name)
            assert rel(ex, fe) < 1e-7
            rods[(bc_name, what)] = ex
            say("   %-26s %15.7f %15.7f %10.1e" % ("%s %s 1" % (bc_name, what), ex, fe, rel(ex, fe)))
    say("   clamped-free f = (1/4L) sqrt(k/m), free-free f = (1/2L) sqrt(k/m); "
        "torsion k/m = G J/(rho I_p), axial E/rho")

    # --- ordering
    for bc_name, n_rigid in (("clamped-free", 0), ("free-free", 6)):
        modes = []
        for d in ("y", "z"):
            more = freqs[(bc_name, d)]["ordering"]
            assert more[-1] > F_ORDER, "compute more bending modes for the ordering"
            for i, f in enumerate(more):
                modes.append((f, "bending in %s, mode %d" % (d, i + 1)))
        for what in ("torsion", "axial"):
            modes.append((rods[(bc_name, what)], "%s, mode 1" % what))
        modes.sort()
        say("")
        say("Mode ordering below %g Hz, %s (bending: Timoshenko, Cowper)%s:" % (
            F_ORDER, bc_name, "; a 3D free-free model first has 6 rigid-body modes ~ 0 Hz (indices 1-6)"
            if n_rigid else ""))
        k = n_rigid
        for f, label in modes:
            if f < F_ORDER:
                k += 1
                say("   %2d  %10.3f Hz  %s" % (k, f, label))
        nxt = [m for m in modes if m[0] >= F_ORDER][:2]
        say("   next: " + "; ".join("%.1f Hz (%s)" % m for m in nxt))

    # the exact determinant in the Euler-Bernoulli limit (kGA -> inf, rho I -> 0)
    worst_eb = 0.0
    for bc_name, bcs in bc_sets.items():
        tb = Timoshenko(Iy, 1e8)
        tb.rI *= 1e-12
        eb = freqs[(bc_name, "y")]["euler_bernoulli"]
        lim = tb.frequencies(bcs, N_MODES, TWO_PI * eb[0]) / TWO_PI
        worst_eb = max(worst_eb, np.max(np.abs(lim - eb) / eb))
    assert worst_eb < 1e-6, worst_eb

    say("")
    n_above, worst_self = selftest_above_cutoff()
    assert worst_self < TOL_FREQ, worst_self
    say("Timoshenko cross-check: exact determinant vs FE, max rel. diff over all bending modes above: %.1e "
        "(required < %.0e)" % (worst_timo, TOL_FREQ))
    say("Self-test of the above-cut-off branch (deep beam L/h = 2, 8 modes clamped-free + free-free, "
        "%d above f_c): max rel. diff %.1e" % (n_above, worst_self))
    say("Exact determinant in the Euler-Bernoulli limit (kappa = 1e8, rho I * 1e-12) vs beta*L roots: "
        "max rel. diff %.1e" % worst_eb)

    if args.yaml:
        print(yaml_snippet(res, freqs, rods))
    else:
        print("\n".join(out))


def yaml_snippet(res, freqs, rods):
    g = lambda v: "%.6e" % v        # 7 significant digits
    gl = lambda a: "[" + ", ".join(g(v) for v in a) + "]"
    lines = [
        "# Reference values from scripts/reference/beam_theory.py (beam theory, 7 significant digits).",
        "# Beam L=1 m, h=0.05 m (y), b=0.1 m (z), E=2.1e11 Pa, nu=0.3, rho=7850 kg/m^3.",
        "# Timoshenko values use Cowper's kappa unless the key says 5_6.",
        "beam_theory:",
        "  kappa: {cowper: %s, five_sixths: %s}" % (g(KAPPAS["cowper"]), g(KAPPAS["5/6"])),
        "  section: {A: %s, I_y_bending: %s, I_z_bending: %s, J: %s, I_p: %s}" % tuple(
            g(res["section"][k]) for k in ("A", "I_y_bending", "I_z_bending", "J", "I_p")),
        "  cantilever_tip_uy:   # m, tip force %s N in -y" % g(P),
        "    euler_bernoulli: %s" % g(res["tip_uy"]["euler_bernoulli"]),
        "    timoshenko: %s" % g(res["tip_uy"]["timoshenko_cowper"]),
        "    timoshenko_5_6: %s" % g(res["tip_uy"]["timoshenko_5/6"]),
    ]
    for bc_name in ("clamped-free", "free-free"):
        lines.append("  %s_hz:%s" % (bc_name.replace("-", "_"),
                                      "   # elastic modes; rigid-body modes are 0" if bc_name == "free-free" else ""))
        for d in ("y", "z"):
            e = freqs[(bc_name, d)]
            lines.append("    bending_%s:" % d)
            lines.append("      euler_bernoulli: %s" % gl(e["euler_bernoulli"]))
            lines.append("      timoshenko: %s" % gl(e["timoshenko_cowper"]))
            lines.append("      timoshenko_5_6: %s" % gl(e["timoshenko_5/6"]))
        lines.append("    torsion_1: %s" % g(rods[(bc_name, "torsion")]))
        lines.append("    axial_1: %s" % g(rods[(bc_name, "axial")]))
    return "\n".join(lines)


if __name__ == "__main__":
    main()
