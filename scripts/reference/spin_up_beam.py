#!/usr/bin/env python3
"""Reference solution of the spin-up beam (Simo & Vu-Quoc 1986; Kane, Ryan & Banerjee 1987).

Problem. A straight beam, L = 10 m, EA = 2.8e7 N, EI = 1.4e4 N m^2, rho A = 1.2 kg/m, is clamped
at its root to a hub on the rotation axis (hub radius 0). The hub turns about the axis z,
perpendicular to the beam, and the beam moves in the plane of rotation. There is no gravity. The
hub angle is prescribed (T_s = 15 s):
    theta(t) = (w_s/T_s) (t^2/2 + (T_s/2pi)^2 (cos(2pi t/T_s) - 1))   for t < T_s,
    theta(t) = w_s (t - T_s/2)                                      for t >= T_s,
so that theta' = (w_s/T_s)(t - (T_s/2pi) sin(2pi t/T_s)) rises smoothly from 0 to w_s, and
theta'' = (w_s/T_s)(1 - cos(2pi t/T_s)) peaks at 2 w_s/T_s at t = T_s/2.

Observable and sign convention. The hub frame has e1 = (cos theta, sin theta) along the undeformed
beam and e2 = (-sin theta, cos theta) = e_z x e1. Positive theta turns counter-clockwise about +z,
so e2 points in the direction of the rotation. The tip deflection is v_tip = r_tip . e2, the
component perpendicular to the undeformed axis in the hub frame. A negative v_tip means the tip
lags behind the hub.

Three models.

Notation: ' on theta and q is d/dt; on x, y, phi (model A) and on phi_i, v (model B) it is d/ds
or d/dx along the beam.

(A) Geometrically exact planar beam FE (the Simo-Reissner beam, as in Simo & Vu-Quoc), in the
    inertial frame. Unknowns per node: position (x, y) and section angle phi. The strains are
        eps = cos(phi) x' + sin(phi) y' - 1,   gam = -sin(phi) x' + cos(phi) y',   kap = phi',
    and the strain energy is (1/2) int (EA eps^2 + GA gam^2 + EI kap^2) ds. The elements are
    2-node and linear, with one-point (midpoint) integration, which avoids shear locking. The
    tangent is analytic and is checked against central differences. The mass is consistent and
    constant: rho A for x and y, rho I for phi. Centrifugal stiffening is not added as a term: it
    comes out of the exact kinematics. The root node has x = y = 0 and phi = theta(t) prescribed.
    Time integration: generalized-alpha (Chung & Hulbert 1993, in the form of Arnold & Bruls
    2007: equilibrium M a_{n+1} + f_int(q_{n+1}) = 0 at t_{n+1}), with rho_inf = 0.9, which damps
    the unresolved axial modes. Each step is solved by Newton on a_{n+1} with a banded LU. The
    section data not given by the problem: GA = 1e7 N (chosen) and rho I = rho A I/A = 6e-4 kg m
    with I/A = EI/EA = 5e-4 m^2. Sensitivity runs with GA = 1e9, rho I = 0 and
    EA * 100 change v_min by 2.4e-5, 8e-6 and 1.3e-5 m (w_s = 4).

(B) Floating frame in the hub frame, with modal coordinates and second-order axial-transverse
    coupling (Kane et al.). The beam is Euler-Bernoulli and inextensible. Its transverse
    displacement is v(x, t) = sum_i phi_i(x) q_i(t), with phi_i the clamped-free cantilever
    modes. The axial displacement is the foreshortening u(x) = -(1/2) int_0^x v'^2. In the hub
    frame, the inertial velocity is (du/dt - theta' v) e1 + (dv/dt + theta' (x + u)) e2. The
    kinetic energy is kept to second order in q. With
        M = int rho A phi phi^T = rho A L I,   K = int EI phi'' phi''^T = diag(EI beta_i^4 L),
        b = int rho A x phi,   K_G = int (1/2) rho A (L^2 - x^2) phi' phi'^T,
    Lagrange's equations read
        M q'' + [K + theta'^2 (K_G - M)] q = -theta'' b,      v_tip = phi(L)^T q.
    K_G is the centrifugal (geometric) stiffening: int rho A x u dx = -(1/2) q^T K_G q after
    integration by parts. -theta'^2 M is the centrifugal softening of the transverse motion.
    The ODE is integrated with scipy's DOP853 (rtol 1e-10), so neither the discretisation nor
    the integrator is shared with (A). The matrices come from composite Gauss quadrature, and the
    modes use an overflow-free form.

(L) The linear floating-frame model is (B) without K_G:
        M q'' + (K - theta'^2 M) q = -theta'' b.
    Mode 1 has the stiffness EI beta_1^4 L - theta'^2 rho A L, which becomes negative once
    theta' exceeds omega_1 = 3.516 sqrt(EI/(rho A L^4)) = 3.80 rad/s. After T_s, q_1 then grows
    like exp(sqrt(w_s^2 - omega_1^2) t). This is the known failure of linear floating-frame
    models.

Checks asserted by the script: FE tangent vs central differences; modal orthonormality;
|(A) - (B)| < 1 % for the minimum tip deflection (found: 4.5e-4 at w_s = 4, the size of the
O((v/L)^2) kinematics that (B) drops, see the summary); the steady-spin oscillation
frequency of (A) vs the eigenvalue of (B) (1 %); the growth rate of (L) vs
sqrt(w_s^2 - omega_1^2) (1 %); the steady centrifugal stretch of (A) vs rho A w^2 L^3/(3 EA) (1 %).

Usage:  /usr/bin/python3 scripts/reference/spin_up_beam.py      (40-70 s, one core)
Writes scripts/reference/spin_up_beam_omega4.csv: t [s], tip deflection [m] of model (A), with 80
elements and dt = 0.0025 s, every 0.05 s over 0..30 s.
(needs numpy and scipy, e.g. Debian's python3-numpy python3-scipy)
"""
import math
import os
import sys
import time

try:
    import numpy as np
    from scipy.integrate import solve_ivp
    from scipy.linalg import eigh, solve_banded
    from scipy.optimize import brentq, minimize_scalar
except ImportError as exc:  # pragma: no cover
    sys.exit(f"spin_up_beam.py needs numpy and scipy ({exc}); "
             "e.g. apt-get install python3-numpy python3-scipy and run /usr/bin/python3")

# ----------------------------------------------------------------------------- data
L = 10.0            # m
EA = 2.8e7          # N
EI = 1.4e4          # N m^2
RHO_A = 1.2         # kg/m
GA = 1.0e7          # N, shear stiffness (model A only; not given by the problem)
RHO_I = RHO_A * EI / EA  # kg m, rotary inertia rho A (I/A), I/A = EI/EA = 5e-4 m^2 (model A only)
T_S = 15.0          # s, spin-up time
T_END = 30.0        # s
OMEGAS = (2.0, 4.0, 6.0)
OMEGA_REF = 4.0
RHO_INF = 0.9       # generalized-alpha spectral radius at infinity
CSV_STEP = 0.05     # s
HERE = os.path.dirname(os.path.abspath(__file__))
CSV_PATH = os.path.join(HERE, "spin_up_beam_omega4.csv")

# discretisations
FE_MESHES = (10, 20, 40, 80)          # element study at dt = FE_DT
FE_DT = 0.01
FE_STEPS = (0.02, 0.01, 0.005, 0.0025)  # time-step study at FE_NEL elements
FE_NEL = 40
FE_FINE = (80, 0.0025)                 # the run written to the CSV (omega_s = 4)
FE_OTHER = ((40, 0.01), (80, 0.005))   # omega_s = 2, 6: a run and a finer one for the error
EB_LIMIT = {"ga": 1e9, "rho_i": 0.0, "ea": 100 * EA}   # model (A) with model (B)'s beam
MODES = (1, 2, 3, 4, 6, 8, 10)         # mode study (omega_s = 4)
N_MODES = 10                           # converged modal model
N_MODES_LIN = 4                        # linear model (decoupled modes, only mode 1 matters)


def hub_angle(t, ws):
    """theta, theta', theta'' of the spin-up profile (t scalar or array)."""
    t = np.asarray(t, dtype=float)
    a = 2.0 * math.pi / T_S
    up = t < T_S
    th = np.where(up, ws / T_S * (0.5 * t * t + (np.cos(a * t) - 1.0) / a**2), ws * (t - 0.5 * T_S))
    thd = np.where(up, ws / T_S * (t - np.sin(a * t) / a), ws)
    thdd = np.where(up, ws / T_S * (1.0 - np.cos(a * t)), 0.0)
    return th, thd, thdd


def parabola_min(t, v):
    """Minimum of sampled v(t): the parabola through the lowest sample and its two neighbours."""
    i = int(np.argmin(v))
    i = min(max(i, 1), len(v) - 2)
    vm, v0, vp = v[i - 1], v[i], v[i + 1]
    d2 = vm - 2.0 * v0 + vp
    h = t[i + 1] - t[i]
    if d2 <= 0.0:
        return t[i], v0
    s = 0.5 * (vm - vp) / d2
    return t[i] + s * h, v0 - 0.125 * (vm - vp) ** 2 / d2


def crossing_period(t, v):
    """Mean period of v(t) - mean(v) from its upward zero crossings (linear interpolation)."""
    w = v - v.mean()
    k = np.nonzero((w[:-1] < 0.0) & (w[1:] >= 0.0))[0]
    tc = t[k] - w[k] * (t[k + 1] - t[k]) / (w[k + 1] - w[k])
    return (tc[-1] - tc[0]) / (len(tc) - 1), len(tc) - 1


# ----------------------------------------------------------------------------- (A) Simo-Reissner FE
def element_forces(q, le, ga=GA, ea=EA, tangent=True):
    """Internal forces f (n_el x 6) and tangents K (n_el x 6 x 6) of all elements at once.

    Element DOFs (x1, y1, phi1, x2, y2, phi2). Midpoint integration: x' = (x2 - x1)/le,
    phi_m = (phi1 + phi2)/2. With c, s = cos, sin phi_m:
      d eps/d dofs = B_e = (-c, -s, le gam/2, c, s, le gam/2)/le,
      d gam/d dofs = B_g = (s, -c, -le (1+eps)/2, -s, c, -le (1+eps)/2)/le,
      d kap/d dofs = (0, 0, -1, 0, 0, 1)/le,
    f = le (N B_e + V B_g + M B_k), with N = EA eps, V = GA gam, M = EI kap.
    K = le (EA B_e B_e^T + GA B_g B_g^T + EI B_k B_k^T) + le (N d2eps + V d2gam). The second
    derivatives couple the translations with phi_m, and phi_m with itself:
      d2eps/dphi_m^2 = -(1 + eps),  d2gam/dphi_m^2 = -gam."""
    X, Y, P = q[0::3], q[1::3], q[2::3]
    dx = (X[1:] - X[:-1]) / le
    dy = (Y[1:] - Y[:-1]) / le
    pm = 0.5 * (P[1:] + P[:-1])
    c, s = np.cos(pm), np.sin(pm)
    eps = c * dx + s * dy - 1.0
    gam = -s * dx + c * dy
    kap = (P[1:] - P[:-1]) / le
    N, V, Mb = ea * eps, ga * gam, EI * kap
    ne = len(dx)
    Be = np.empty((ne, 6))
    Bg = np.empty((ne, 6))
    Be[:, 0], Be[:, 1], Be[:, 3], Be[:, 4] = -c / le, -s / le, c / le, s / le
    Be[:, 2] = Be[:, 5] = 0.5 * gam
    Bg[:, 0], Bg[:, 1], Bg[:, 3], Bg[:, 4] = s / le, -c / le, -s / le, c / le
    Bg[:, 2] = Bg[:, 5] = -0.5 * (1.0 + eps)
    f = le * (N[:, None] * Be + V[:, None] * Bg)
    f[:, 2] -= Mb
    f[:, 5] += Mb
    if not tangent:
        return f, None
    K = le * (ea * Be[:, :, None] * Be[:, None, :] + ga * Bg[:, :, None] * Bg[:, None, :])
    kb = EI / le
    K[:, 2, 2] += kb
    K[:, 5, 5] += kb
    K[:, 2, 5] -= kb
    K[:, 5, 2] -= kb
    g = np.empty((ne, 4))   # le * d(N B_e + V B_g)_translations / d phi_m
    g[:, 0] = N * s + V * c
    g[:, 1] = -N * c + V * s
    g[:, 2] = -g[:, 0]
    g[:, 3] = -g[:, 1]
    tr = [0, 1, 3, 4]
    for p in (2, 5):
        K[:, tr, p] += 0.5 * g
        K[:, p, tr] += 0.5 * g
    h = -0.25 * le * (N * (1.0 + eps) + V * gam)
    for p in (2, 5):
        for r in (2, 5):
            K[:, p, r] += h
    return f, K


def check_tangent(forces=None, ea=EA, ga=GA, ei=EI, le=0.7, amplitude=0.2, seed=1):
    """Max relative deviation of the analytic f and K of `forces` (default: element_forces)
    from central differences of the energy and of f, at a random large deformation of 4
    elements of length le with section data ea, ga, ei."""
    forces = forces or element_forces
    rng = np.random.default_rng(seed)
    ne = 4
    q = np.zeros(3 * (ne + 1))
    q[0::3] = np.arange(ne + 1) * le
    q += amplitude * rng.standard_normal(q.size)

    def energy(qq):
        X, Y, P = qq[0::3], qq[1::3], qq[2::3]
        dx, dy = np.diff(X) / le, np.diff(Y) / le
        pm = 0.5 * (P[1:] + P[:-1])
        e = np.cos(pm) * dx + np.sin(pm) * dy - 1.0
        g = -np.sin(pm) * dx + np.cos(pm) * dy
        k = np.diff(P) / le
        return 0.5 * le * np.sum(ea * e * e + ga * g * g + ei * k * k)

    f, K = forces(q, le)
    F = np.zeros(q.size)
    for e in range(ne):
        F[3 * e:3 * e + 6] += f[e]
    h = 1e-6
    err_f = err_k = 0.0
    for i in range(q.size):
        dq = np.zeros(q.size)
        dq[i] = h
        fd = (energy(q + dq) - energy(q - dq)) / (2 * h)
        err_f = max(err_f, abs(fd - F[i]) / np.abs(F).max())
    for e in range(ne):   # every element's tangent, column by column
        for i in range(6):
            dq = np.zeros(q.size)
            dq[3 * e + i] = h
            fp, _ = forces(q + dq, le, tangent=False)
            fm, _ = forces(q - dq, le, tangent=False)
            err_k = max(err_k, np.abs((fp[e] - fm[e]) / (2 * h) - K[e, :, i]).max() /
                        np.abs(K[e]).max())
    return err_f, err_k


def alpha_parameters(rho_inf, dt):
    """Chung-Hulbert generalized-alpha parameters alpha_m, alpha_f, gamma, beta and
    dq/da = dt^2 beta (1 - alpha_f) / (1 - alpha_m) of a step in the algorithmic acceleration."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gm = 0.5 + af - am
    beta = 0.25 * (gm + 0.5) ** 2
    return am, af, gm, beta, dt * dt * beta * (1.0 - af) / (1.0 - am)


def band_pattern(n_el, nf, ku, fixed):
    """Scatter indices of the 6 x 6 element blocks of n_el 2-node elements (3 DOFs per node) into
    the band storage (half bandwidth ku) of the nf free DOFs, the first `fixed` DOFs removed:
    band indices and the mask of kept block entries, element-force indices and their mask."""
    e = np.arange(n_el)
    A_, B_ = np.meshgrid(np.arange(6), np.arange(6), indexing="ij")
    gi = 3 * e[:, None, None] + A_[None] - fixed
    gj = 3 * e[:, None, None] + B_[None] - fixed
    ok = (gi >= 0) & (gj >= 0)
    band_idx = ((ku + gi - gj) * nf + gj)[ok]
    f_idx = 3 * e[:, None] + np.arange(6)[None, :] - fixed
    f_ok = f_idx >= 0
    return band_idx, ok, f_idx[f_ok], f_ok


def run_fe(ws, n_el, dt, t_end=T_END, ga=GA, rho_i=RHO_I, ea=EA, rho_inf=RHO_INF):
    """Model (A). Returns dict(t, v = tip deflection in the hub frame, u = tip axial displacement
    in the hub frame, newton = mean Newton iterations per step, wall)."""
    t0 = time.time()
    le = L / n_el
    nn = n_el + 1
    nd = 3 * nn
    nf = nd - 3                      # free DOFs: nodes 1..n_el
    ku = 5                           # half bandwidth (3 DOFs per node, neighbour coupling)
    # consistent mass, banded over the free DOFs, plus the coupling to the prescribed root
    # rotation (the root translations are fixed at 0)
    mdiag = np.array([RHO_A, RHO_A, rho_i])
    Mb = np.zeros((2 * ku + 1, nf))
    for node in range(1, nn):
        for d in range(3):
            i = 3 * node + d - 3
            Mb[ku, i] += mdiag[d] * le * (2.0 if node == n_el else 4.0) / 6.0
            if node < n_el:            # coupling with the next node, same component
                Mb[ku + 3, i] += mdiag[d] * le / 6.0      # row i+3, column i
                Mb[ku - 3, i + 3] += mdiag[d] * le / 6.0  # row i, column i+3
    m_root_phi = rho_i * le / 6.0        # M[phi_1, phi_0]

    def mass_times(a_f):
        out = Mb[ku] * a_f
        out[3:] += Mb[ku + 3, :-3] * a_f[:-3]
        out[:-3] += Mb[ku - 3, 3:] * a_f[3:]
        return out

    # scatter pattern of element tangents into the band of the free DOFs
    band_idx, ok, f_idx, f_ok = band_pattern(n_el, nf, ku, 3)

    am, af, gm, beta, dq_da = alpha_parameters(rho_inf, dt)

    q = np.zeros(nd)
    q[0::3] = np.arange(nn) * le
    v = np.zeros(nd)
    a = np.zeros(nd)        # initial acceleration: straight beam at rest, theta''(0) = 0
    abar = np.zeros(nd)
    n_steps = int(round(t_end / dt))
    ts = dt * np.arange(n_steps + 1)
    th_all, thd_all, thdd_all = hub_angle(ts, ws)
    tip_x = np.zeros(n_steps + 1)
    tip_y = np.zeros(n_steps + 1)
    tip_x[0] = L
    iters = 0
    tol = 1e-11 * L
    for n in range(n_steps):
        th, thd, thdd = th_all[n + 1], thd_all[n + 1], thdd_all[n + 1]
        q_hat = q + dt * v + dt * dt * (0.5 - beta) * abar
        v_hat = v + dt * (1.0 - gm) * abar
        abar_c = (af * a - am * abar) / (1.0 - am)   # abar_{n+1} = abar_c + (1-af)/(1-am) a_{n+1}
        a_new = a.copy()
        a_new[:3] = (0.0, 0.0, thdd)
        for it in range(25):
            ab_new = abar_c + (1.0 - af) / (1.0 - am) * a_new
            q_new = q_hat + dt * dt * beta * ab_new
            q_new[:3] = (0.0, 0.0, th)
            f, K = element_forces(q_new, le, ga, ea)
            r = mass_times(a_new[3:]) + np.bincount(f_idx, f[f_ok], minlength=nf)
            r[2] += m_root_phi * thdd
            S = Mb + dq_da * np.bincount(band_idx, K[ok], minlength=(2 * ku + 1) * nf).reshape(2 * ku + 1, nf)
            da = solve_banded((ku, ku), S, -r, check_finite=False)
            a_new[3:] += da
            iters += 1
            if np.abs(da).max() * dq_da < tol:
                break
        else:
            raise RuntimeError("Newton did not converge at t = %g" % ts[n + 1])
        ab_new = abar_c + (1.0 - af) / (1.0 - am) * a_new
        q = q_hat + dt * dt * beta * ab_new
        v = v_hat + dt * gm * ab_new
        q[:3] = (0.0, 0.0, th)
        v[:3] = (0.0, 0.0, thd)
        a, abar = a_new, ab_new
        tip_x[n + 1], tip_y[n + 1] = q[-3], q[-2]
    c, s = np.cos(th_all), np.sin(th_all)
    return {"t": ts, "v": -s * tip_x + c * tip_y, "u": c * tip_x + s * tip_y - L,
            "newton": iters / n_steps, "wall": time.time() - t0}


# ----------------------------------------------------------------------------- (B) modal model
def cantilever_roots(n):
    """beta_i L: roots of 1 + cos x cosh x = 0, written as cos x + 1/cosh x = 0."""
    f = lambda x: math.cos(x) + 1.0 / math.cosh(x)
    out = []
    for k in range(n):
        lo = 1.0 if k == 0 else (k + 0.5) * math.pi - 0.4
        out.append(brentq(f, lo, (k + 0.5) * math.pi + 0.4, xtol=1e-15, rtol=1e-15))
    return np.array(out)


def cantilever_modes(n, x):
    """phi_i(x), phi_i'(x) (n x len(x)) normalised to int_0^L phi^2 = L:
        phi = cosh z - cos z - sig (sinh z - sin z),  z = beta x,
        sig = (cosh bL + cos bL)/(sinh bL + sin bL).
    cosh z - sig sinh z = ((1 - sig) e^z + (1 + sig) e^-z)/2 with
    1 - sig = (sin bL - cos bL - e^-bL)/(sinh bL + sin bL), free of cancellation."""
    bl = cantilever_roots(n)
    phi = np.empty((n, len(x)))
    dphi = np.empty((n, len(x)))
    for i, BL in enumerate(bl):
        b = BL / L
        z = b * x
        den = math.sinh(BL) + math.sin(BL)
        sig = (math.cosh(BL) + math.cos(BL)) / den
        oms_ez = (math.sin(BL) - math.cos(BL) - math.exp(-BL)) / den * np.exp(z)
        ch = 0.5 * (oms_ez + (1.0 + sig) * np.exp(-z))     # cosh z - sig sinh z
        sh = 0.5 * (oms_ez - (1.0 + sig) * np.exp(-z))     # sinh z - sig cosh z
        phi[i] = ch - np.cos(z) + sig * np.sin(z)
        dphi[i] = b * (sh + np.sin(z) + sig * np.cos(z))
    return bl, phi, dphi


def modal_matrices(n, panels=8, points=100):
    """M, K, K_G, b and phi(L) of model (B), by composite Gauss-Legendre quadrature."""
    g, w = np.polynomial.legendre.leggauss(points)
    h = L / panels
    x = np.concatenate([(p + 0.5 * (g + 1.0)) * h for p in range(panels)])
    wq = np.tile(0.5 * h * w, panels)
    bl, phi, dphi = cantilever_modes(n, x)
    M = RHO_A * (phi * wq) @ phi.T
    K = np.diag(EI * (bl / L) ** 4 * L)
    KG = (dphi * (wq * 0.5 * RHO_A * (L * L - x * x))) @ dphi.T
    b = RHO_A * (phi * wq) @ x
    _, phiL, _ = cantilever_modes(n, np.array([L]))
    return M, K, KG, b, phiL[:, 0]


def run_modal(ws, n, stiffening=True, t_end=T_END, rtol=1e-10):
    """Model (B) (stiffening=True) or (L). Returns dict(sol, phiL, n, wall, vtip(t))."""
    t0 = time.time()
    M, K, KG, b, phiL = modal_matrices(n)
    Minv = np.linalg.inv(M)
    MK, MKG, Mb = Minv @ K, Minv @ (KG if stiffening else np.zeros_like(KG)), Minv @ b

    def rhs(t, y):
        q, qd = y[:n], y[n:]
        _, thd, thdd = hub_angle(t, ws)
        qdd = -(MK @ q) - thd * thd * (MKG @ q - q) - thdd * Mb
        return np.concatenate([qd, qdd])

    sol = solve_ivp(rhs, (0.0, t_end), np.zeros(2 * n), method="DOP853", rtol=rtol,
                    atol=1e-12, dense_output=True, max_step=0.1)
    assert sol.success, sol.message
    vtip = lambda t: phiL @ sol.sol(t)[:n]
    return {"sol": sol, "vtip": vtip, "n": n, "wall": time.time() - t0,
            "M": M, "K": K, "KG": KG}


def modal_min(res, first=False):
    """Minimum of the dense tip deflection on [0, T_END], refined by Brent: the global one, or
    (first=True) the first local minimum (None if there is none)."""
    tt = np.linspace(0.0, T_END, int(round(T_END / 0.01)) + 1)
    vv = res["vtip"](tt)
    if first:
        k = np.nonzero((vv[1:-1] < vv[:-2]) & (vv[1:-1] <= vv[2:]))[0]
        if len(k) == 0:
            return None, None
        i = k[0] + 1
    else:
        i = min(max(int(np.argmin(vv)), 1), len(tt) - 2)
    r = minimize_scalar(res["vtip"], bracket=(tt[i - 1], tt[i], tt[i + 1]), tol=1e-12)
    return r.x, float(r.fun)


# ----------------------------------------------------------------------------- report
def main():
    t_start = time.time()
    out = []

    def say(s=""):
        print(s, flush=True)
        out.append(s)

    omega1 = cantilever_roots(1)[0] ** 2 * math.sqrt(EI / (RHO_A * L**4))
    say("Spin-up beam: L = %g m, EA = %g N, EI = %g N m^2, rho A = %g kg/m, T_s = %g s, hub radius 0"
        % (L, EA, EI, RHO_A, T_S))
    say("First cantilever bending frequency omega_1 = %.4f rad/s (%.4f Hz)" % (omega1, omega1 / (2 * math.pi)))
    say("Sign: v_tip = r_tip . e2, e2 = e_z x e1 points in the direction of rotation; v_tip < 0 = tip lags")
    say()

    # ---- self-checks
    err_f, err_k = check_tangent()
    assert err_f < 1e-6 and err_k < 1e-6, (err_f, err_k)
    M10, K10, KG10, _, _ = modal_matrices(N_MODES)
    orth = np.abs(M10 / (RHO_A * L) - np.eye(N_MODES)).max()
    assert orth < 1e-9, orth
    southwell = KG10[0, 0] / M10[0, 0]
    say("Checks: FE force vs d(energy) and tangent vs d(force) (central differences): %.1e, %.1e;"
        % (err_f, err_k))
    say("        modes: |M/(rho A L) - I| = %.1e (%d modes); K_G11/M11 = %.4f (the Southwell coefficient"
        % (orth, N_MODES, southwell))
    say("        of mode 1; steady in-plane frequency^2 = omega_1^2 + (K_G11/M11 - 1) w^2 with one mode)")
    say()

    # ---- omega_s = 4: convergence studies
    ws = OMEGA_REF
    say("Convergence, w_s = %g rad/s: minimum tip deflection v_min [m] and its time t_min [s]" % ws)
    say()
    say("(A) Simo-Reissner FE, generalized-alpha rho_inf = %g" % RHO_INF)
    say("   %6s %8s %14s %10s %10s %8s %8s" % ("n_el", "dt [s]", "v_min [m]", "t_min [s]", "change", "Newton", "wall [s]"))
    fe_runs = {}

    def fe(ws_, n_el, dt):
        key = (ws_, n_el, dt)
        if key not in fe_runs:
            res = run_fe(ws_, n_el, dt)
            res["t_min"], res["v_min"] = parabola_min(res["t"], res["v"])
            fe_runs[key] = res
        return fe_runs[key]

    def refinement(levels, label):
        """Runs the levels [(n_el, dt)], prints a table row each and the observed order."""
        prev, vals = None, []
        for n_el, dt in levels:
            r = fe(ws, n_el, dt)
            vals.append(r["v_min"])
            say("   %6d %8g %14.7f %10.4f %10s %8.2f %8.1f" % (n_el, dt, r["v_min"], r["t_min"],
                "" if prev is None else "%.2e" % (r["v_min"] - prev), r["newton"], r["wall"]))
            prev = r["v_min"]
        d = np.diff(vals)
        p = np.log2(d[:-1] / d[1:])
        say("   observed order in %s: %s (expected 2)" % (label, ", ".join("%.2f" % x for x in p)))
        return vals, p

    mesh_vals, p_mesh = refinement([(n, FE_DT) for n in FE_MESHES], "n_el")
    step_vals, p_step = refinement([(FE_NEL, dt) for dt in FE_STEPS], "dt")
    fine = fe(ws, *FE_FINE)
    say("   %6d %8g %14.7f %10.4f %10s %8.2f %8.1f   <- written to the CSV"
        % (FE_FINE[0], FE_FINE[1], fine["v_min"], fine["t_min"], "", fine["newton"], fine["wall"]))
    # separable Richardson: v(n, dt) = v* + a/n^2 + b dt^2, both corrections taken from the two
    # finest levels; the uncertainty is the change of each correction against the next coarser
    # pair plus the remainder of the finest run.
    i40 = FE_MESHES.index(FE_NEL)
    corr_mesh = (mesh_vals[-1] - mesh_vals[-2]) / 3.0              # v(80) -> v(inf) at FE_DT
    corr_mesh_c = (mesh_vals[-2] - mesh_vals[-3]) / 3.0 / 4.0      # same from (20, 40), scaled to 80
    corr_step = (step_vals[-1] - step_vals[-2]) / 3.0              # v(dt_min) -> v(0) at FE_NEL
    corr_step_c = (step_vals[-2] - step_vals[-3]) / 3.0 / 4.0
    j_dt = FE_STEPS.index(FE_DT)
    # v* = v(80, dt_min) - (v(80) - v(inf)) - (v(dt_min) - v(0)), with the separable model
    v_fine_model = mesh_vals[-1] + (step_vals[-1] - step_vals[j_dt])   # prediction of v(80, 0.0025)
    v_fe = fine["v_min"] + corr_mesh + corr_step
    u_fe = abs(corr_mesh - corr_mesh_c) + abs(corr_step - corr_step_c) + abs(fine["v_min"] - v_fine_model)
    t_fe = fine["t_min"]
    say("   separable model check: v(%d, %g) predicted from the studies %.7f, computed %.7f"
        % (FE_FINE[0], FE_FINE[1], v_fine_model, fine["v_min"]))
    say("   extrapolated (Richardson in n_el and dt): v_min = %.6f m +- %.1e" % (v_fe, u_fe))
    say()

    # sensitivity to the section data: model (A) in the limit of model (B)'s beam
    # (Euler-Bernoulli: GA -> inf, rho I = 0; and EA * 100, nearly inextensible)
    base = fe(ws, FE_NEL, FE_DT)["v_min"]
    for label, kw in (("GA = 1e9 N", {"ga": 1e9}), ("rho I = 0", {"rho_i": 0.0}),
                      ("EA * 100", {"ea": 100 * EA}), ("all three (Euler-Bernoulli, inextensible limit)", EB_LIMIT)):
        r = run_fe(ws, FE_NEL, FE_DT, **kw)
        say("   sensitivity at %d el., dt %g: %-48s v_min change %+.1e m" % (FE_NEL, FE_DT, label, parabola_min(r["t"], r["v"])[1] - base))
    # steady spin: axial stretch and oscillation frequency
    tail = fine["t"] >= T_S + 1.0
    u_mean = fine["u"][tail].mean()
    u_ex = RHO_A * ws**2 * L**3 / (3.0 * EA)
    say("   steady spin t > %g s: mean axial tip displacement %.4e m (rod: rho A w^2 L^3/(3EA) = %.4e m;"
        % (T_S + 1, u_mean, u_ex))
    say("      the difference is the foreshortening of the residual bending, ~ -v^2/L)")
    assert abs(u_mean - u_ex) / u_ex < 1e-2, (u_mean, u_ex)
    say()

    say("(B) floating frame, cantilever modes + centrifugal stiffening K_G, DOP853 rtol 1e-10")
    say("   %6s %14s %10s %10s %8s" % ("modes", "v_min [m]", "t_min [s]", "change", "wall [s]"))
    prev = None
    modal_vals = {}
    modal_runs = {}
    for n in MODES:
        r = run_modal(ws, n)
        t_m, v_m = modal_min(r)
        modal_vals[n] = (t_m, v_m)
        modal_runs[n] = r
        say("   %6d %14.7f %10.4f %10s %8.1f" % (n, v_m, t_m, "" if prev is None else "%.2e" % (v_m - prev), r["wall"]))
        prev = v_m
    t_mod, v_mod = modal_vals[N_MODES]
    u_mod = abs(modal_vals[N_MODES][1] - modal_vals[MODES[-2]][1])
    loose = run_modal(ws, N_MODES, rtol=1e-8)
    u_int = abs(modal_min(loose)[1] - v_mod)
    say("   time integration: rtol 1e-8 instead of 1e-10 changes v_min by %.1e" % u_int)
    say("   converged (%d modes): v_min = %.6f m +- %.1e" % (N_MODES, v_mod, u_mod + u_int))
    say()

    # ---- agreement (A) vs (B)
    rel_ab = abs(v_fe - v_mod) / abs(v_mod)
    say("Agreement (A) vs (B), w_s = %g: v_min %.6f vs %.6f m, rel. diff %.1e (required < 1e-2);"
        % (ws, v_fe, v_mod, rel_ab))
    say("   t_min %.4f vs %.4f s" % (t_fe, t_mod))
    assert rel_ab < 1e-2, rel_ab
    tt = fine["t"][::int(round(CSV_STEP / FE_FINE[1]))]
    vv_fe = fine["v"][::int(round(CSV_STEP / FE_FINE[1]))]
    vv_mod = modal_runs[N_MODES]["vtip"](tt)
    curve_diff = np.abs(vv_fe - vv_mod).max()
    say("   whole curve 0..%g s (every %g s): max |v_A - v_B| = %.1e m (%.2f %% of |v_min|)"
        % (T_END, CSV_STEP, curve_diff, 100 * curve_diff / abs(v_mod)))
    # residual oscillation at steady spin: period of (A) against the eigenvalue of (B)
    per_fe, ncyc = crossing_period(fine["t"][tail], fine["v"][tail])
    lam = eigh(K10 + ws**2 * (KG10 - M10), M10, eigvals_only=True)
    per_mod = 2 * math.pi / math.sqrt(lam[0])
    say("   steady spin: residual oscillation period (A) %.4f s (%d cycles), (B) eigenvalue 2pi/%.4f = %.4f s;"
        % (per_fe, ncyc, math.sqrt(lam[0]), per_mod))
    say("      without stiffening the mode-1 stiffness omega_1^2 - w_s^2 = %.3f rad^2/s^2 < 0" % (omega1**2 - ws**2))
    assert abs(per_fe - per_mod) / per_mod < 1e-2, (per_fe, per_mod)
    post = fine["t"] >= T_S
    say("   after T_s the tip oscillates between %.4f and %.4f m (model A)" % (fine["v"][post].min(), fine["v"][post].max()))
    say()

    # ---- other spin rates and the linear model
    summary = []
    for w in OMEGAS:
        if w == OMEGA_REF:
            ra = {"v_min": v_fe, "t_min": t_fe, "err": u_fe, "disc": "%d el., dt %g + Richardson" % FE_FINE,
                  "wall": fine["wall"]}
        else:
            coarse = fe(w, *FE_OTHER[0])
            finer = fe(w, *FE_OTHER[1])
            ex = finer["v_min"] + (finer["v_min"] - coarse["v_min"]) / 3.0
            ra = {"v_min": ex, "t_min": finer["t_min"], "err": abs(finer["v_min"] - coarse["v_min"]) / 3.0,
                  "disc": "%d el., dt %g + Richardson" % FE_OTHER[1], "wall": coarse["wall"] + finer["wall"]}
        rb = modal_runs[N_MODES] if w == OMEGA_REF else run_modal(w, N_MODES)
        tb, vb = modal_min(rb)
        rl = run_modal(w, N_MODES_LIN, stiffening=False)
        tl, vl = modal_min(rl, first=True)     # first local minimum (during the spin-up)
        tt_l = np.linspace(0.0, T_END, 3001)
        vv_l = rl["vtip"](tt_l)
        big = np.nonzero(np.abs(vv_l) > L)[0]
        # offset of (A) to the Euler-Bernoulli, inextensible limit at (FE_NEL, FE_DT)
        eb = run_fe(w, FE_NEL, FE_DT, **EB_LIMIT)
        offset = parabola_min(eb["t"], eb["v"])[1] - fe(w, FE_NEL, FE_DT)["v_min"]
        rel_eb = abs(ra["v_min"] + offset - vb) / abs(vb)
        info = {"w": w, "A": ra, "B": (tb, vb, rb["wall"]), "L": (tl, vl, rl["wall"]), "rel_eb": rel_eb,
                "L_end": vv_l[-1], "L_blow": tt_l[big[0]] if len(big) else None,
                "L_maxabs": np.abs(vv_l).max()}
        if w > omega1:
            # growth rate of the linear model after T_s against sqrt(w^2 - omega_1^2)
            lo, hi = T_END - 10.0, T_END
            q1 = rl["sol"].sol(np.array([lo, hi]))[0]
            rate = math.log(abs(q1[1] / q1[0])) / (hi - lo)
            info["rate"] = (rate, math.sqrt(w * w - omega1**2))
            assert abs(rate - info["rate"][1]) / info["rate"][1] < 1e-2, info["rate"]
        summary.append(info)

    say("Summary: minimum tip deflection v_min (negative = lagging) and its time t_min")
    say("   %4s  %-36s %-34s %11s %8s %8s" % ("w_s", "model", "discretisation", "v_min [m]", "t_min [s]", "wall [s]"))
    for s in summary:
        ra = s["A"]
        tb, vb, wb = s["B"]
        tl, vl, wl = s["L"]
        say("   %4g  %-36s %-34s %11.6f %8.3f %8.1f" % (s["w"], "(A) geometrically exact FE", ra["disc"], ra["v_min"], ra["t_min"], ra["wall"]))
        say("   %4s  %-36s %-34s %11s %8s %8s" % ("", "", "  discretisation error estimate", "+-%.0e" % ra["err"], "", ""))
        say("   %4s  %-36s %-34s %11.6f %8.3f %8.1f" % ("", "(B) floating frame + K_G", "%d modes, DOP853" % N_MODES, vb, tb, wb))
        if vl is None:
            say("   %4s  %-36s %-34s %11s %8s %8.1f" % ("", "(L) linear floating frame", "%d modes, DOP853" % N_MODES_LIN, "diverges", "", wl))
        else:
            say("   %4s  %-36s %-34s %11.6f %8.3f %8.1f" % ("", "(L) linear floating frame", "%d modes, DOP853" % N_MODES_LIN, vl, tl, wl))
        rel = abs(ra["v_min"] - vb) / abs(vb)
        say("         (A)-(B): %.1e rel.; (A) in the EB/inextensible limit - (B): %.1e rel. = %.2f (v_min/L)^2"
            % (rel, s["rel_eb"], s["rel_eb"] / (vb / L) ** 2))
        if s["L_blow"] is not None:
            rate, rate_ex = s["rate"]
            say("         (L): no minimum, v_tip falls monotonically; |v_tip| > L at t = %.1f s, v_tip(%g s) = %.1e m;"
                % (s["L_blow"], T_END, s["L_end"]))
            say("              growth rate after T_s %.4f 1/s = sqrt(w_s^2 - omega_1^2) = %.4f 1/s" % (rate, rate_ex))
        else:
            say("         (L): bounded, max |v_tip| = %.4f m; v_min %+.1f %% vs (B) (no stiffening, softening -theta'^2 M only)"
                % (s["L_maxabs"], 100 * (vl - vb) / abs(vb)))
    say()

    # ---- CSV
    with open(CSV_PATH, "w") as fh:
        fh.write("t_s,tip_deflection_m\n")
        for t_, v_ in zip(tt, vv_fe):
            fh.write("%.2f,%.7e\n" % (t_, v_))
    say("Wrote %s (%d rows): model (A), %d elements, dt = %g s, w_s = %g rad/s"
        % (os.path.relpath(CSV_PATH), len(tt), FE_FINE[0], FE_FINE[1], OMEGA_REF))
    say("Total run time %.0f s" % (time.time() - t_start))


if __name__ == "__main__":
    main()
