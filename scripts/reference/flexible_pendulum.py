#!/usr/bin/env python3
"""Reference solution of the flexible pendulum (future case cases/flexible_pendulum).

Problem. A slender elastic bar, L = 1 m, square section h = b = 0.02 m, E = 1e10 Pa, nu = 0.3,
rho = 2700 kg/m^3, is pinned at its root (s = 0) to the origin by a revolute joint: the root
position is fixed and its section rotation is free. At t = 0 it lies straight along +x, at rest and
undeformed. Gravity g = 9.81 m/s^2 acts along -y. It is released at t = 0 and falls (clockwise,
phi0 < 0) through the hanging position to the other side, about half a swing in t = 0..1 s.
Section data: A = h^2, I = h^4/12, EA, EI = E I, GA = (5/6) G A with G = E/(2(1+nu)), mass
rho A and rotary inertia rho I per length.

Observable (as the FFRF model measures it). With phi0(t) the section angle at the root,
e1 = (cos phi0, sin phi0), e2 = (-sin phi0, cos phi0) and r = x_tip - x_root:
    u_axial = r.e1 - L,   v_transverse = r.e2,
the tip's elastic displacement in the frame of the root cross-section. v > 0 means the tip is
displaced towards e2 (it lags behind the falling bar). Also reported: phi0(t), tip (x, y).

Models.

(A) Geometrically exact planar beam FE (Simo-Reissner), inertial frame: the element of
    spin_up_beam.py (docs/reference-spin-up-beam.md), imported. Strains
        eps = cos(phi) x' + sin(phi) y' - 1,  gam = -sin(phi) x' + cos(phi) y',  kap = phi',
    energy (1/2) int (EA eps^2 + GA gam^2 + EI kap^2) ds; 2-node linear elements, one-point
    integration, analytic tangent (checked by central differences); consistent mass rho A on
    x, y and rho I on phi. spin_up_beam.element_forces reads its module constant EI; its bending
    part (f_phi1 = -EI kap, f_phi2 = +EI kap, K_phiphi = (EI/le) [[1, -1], [-1, 1]]) is linear in
    EI and uncoupled from the rest, so element_forces below adds (EI - spin_up_beam.EI) times it:
    exact, and checked (identical to spin_up_beam's element at its EI; central differences).
    New here: the root node has x = y = 0 and a FREE section angle phi0 (pinned), and the
    consistent gravity load -rho A g on the y DOFs (le/2 per element end). The equations are
        M a + f_int(q) = f_g,   a(0) = M^-1 f_g (the undeformed bar is force-free at t = 0),
    integrated by generalized-alpha (Arnold & Bruls 2007, as in spin_up_beam.py) with
    rho_inf = 0.9; Newton on a_{n+1}, the iteration matrix M + h^2 beta (1-af)/(1-am) K_T is
    formed and LU-factorised (LAPACK dgbtrf, banded) once per step and reused by the
    following iterations of the step (2 per step; stop at |dq| < 1e-12 m).
    rho_inf = 1.0 is run as a check; the difference is < 1e-6 m (see the report).

(B) Floating frame with modal coordinates and second-order (stiffening) terms, Euler-Bernoulli
    and inextensible, frame = root section (clamped-free cantilever modes phi_i, int phi^2 = L,
    from spin_up_beam.cantilever_modes). Frame angle theta = phi0 (free), transverse
    v(x,t) = sum phi_i(x) q_i, foreshortening u(x) = -(1/2) int_0^x v'^2. With
        J = rho A L^3/3, S = rho A L^2/2, M = rho A L I, K = diag(EI beta_i^4 L),
        b = int rho A x phi, c = int rho A phi, K_G = int (1/2) rho A (L^2 - x^2) phi' phi'^T,
        K_Gg = int rho A (L - x) phi' phi'^T,   M_s = M - K_G,
    the kinetic and potential energies to second order in q are
        T = (1/2) theta'^2 (J + q^T M_s q) + theta' b^T q' + (1/2) q'^T M q',
        V = (1/2) q^T K q + g sin(theta) (S - (1/2) q^T K_Gg q) + g cos(theta) c^T q
    (int rho A x u = -(1/2) q^T K_G q, int rho A u = -(1/2) q^T K_Gg q), and Lagrange gives
        (J + q^T M_s q) theta'' + b^T q'' = -2 theta' q^T M_s q' - g cos(theta) (S - q^T K_Gg q/2)
                                            + g sin(theta) c^T q
        b theta'' + M q'' = theta'^2 M_s q - K q + g sin(theta) K_Gg q - g cos(theta) c.
    K_G is the centrifugal stiffening, -g sin(theta) K_Gg the stiffening by the axial component of
    gravity (tension when hanging). v_transverse = phi(L)^T q, u_axial = -(1/2) q^T K_u q with
    K_u = int phi' phi'^T.
(L) Linear floating frame: (B) with K_G = K_Gg = 0 (no geometric stiffening; the exact
    inertia of the linear field v = sum phi_i q_i, u = 0, including -theta'^2 M).
    (B) and (L) are integrated with scipy's DOP853 (rtol 1e-10); the energy T + V is conserved
    to < 1e-9 J (asserted).
(R) Rigid pendulum, J_R theta'' = -m g (L/2) cos(theta), J_R = rho A L^3/3 + rho I L (the
    rotary inertia of (A)); its half period is checked against the elliptic integral.

(A) is the reference (it has the shear and rotary inertia of the 3D bar, which the FFRF body
clamped to its root face also has). (B) is the independent check of (A): (A) in the
Euler-Bernoulli limit (GA * 1e3, rho I * 1e-3) is compared with (B). (L) vs (A) is the error of a
linear FFRF model here.

Why the convergence is slow. The bar is released with the full gravity load suddenly applied,
so every bending mode is excited and none is damped. In the root frame the pinned-free modes
(171, 553, 1150, 1958, 2968 rad/s) appear in v_tip with amplitudes of about 2e-3, 1.2e-4,
4e-5, 1e-5, 5e-6 m (spectrum of v). A point value v(t) at t ~ 1 s depends on their phases, omega_k t, and the
discretisation error of omega_k grows with k (like (k h)^2 in space, (omega_k dt)^2 in time);
the sum over the modes converges only about linearly in h and dt. The error estimates below
are therefore plain differences between the two finest levels, not Richardson extrapolations.

Usage:  /usr/bin/python3 scripts/reference/flexible_pendulum.py [--jobs N]
    (about 180 s of CPU: 1.5-2 min wall with 2 jobs on an idle machine; N defaults to
    min(2, number of CPUs); 20 runs, the longest (12-mode (B), 512-element (A)) 20-40 s)
Writes scripts/reference/flexible_pendulum.csv: t [s], phi0 [rad], v_transverse [m],
u_axial [m], tip x [m], tip y [m] of model (A) with 512 elements, dt = 2.5e-5 s, every 1e-3 s.
(needs numpy and scipy, e.g. Debian's python3-numpy python3-scipy)
"""
import argparse
import math
import os
import resource
import sys
import time

try:
    import numpy as np
    from multiprocessing import Pool
    from scipy.integrate import solve_ivp
    from scipy.linalg import eigh, solve_banded
    from scipy.linalg.lapack import dgbtrf, dgbtrs
    from scipy.signal import find_peaks
    from scipy.special import ellipk
    from scipy.optimize import brentq, minimize_scalar
except ImportError as exc:  # pragma: no cover
    sys.exit(f"flexible_pendulum.py needs numpy and scipy ({exc}); "
             "e.g. apt-get install python3-numpy python3-scipy and run /usr/bin/python3")

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True   # no __pycache__ next to the scripts
import spin_up_beam as sub  # noqa: E402  (the shared beam element and cantilever modes)

# ----------------------------------------------------------------------------- data
L = 1.0                 # m
H = 0.02                # m, square section h = b
E = 1.0e10              # Pa
NU = 0.3
RHO = 2700.0            # kg/m^3
G_ACC = 9.81            # m/s^2, along -y
A = H * H
I = H**4 / 12.0
EA = E * A
EI = E * I
GA = 5.0 / 6.0 * E / (2.0 * (1.0 + NU)) * A
RHO_A = RHO * A
RHO_I = RHO * I
MASS = RHO_A * L
T_END = 1.0
RHO_INF = 0.9
TIMES = (0.25, 0.5, 0.75, 1.0)
CSV_STEP = 1.0e-3
CSV_PATH = os.path.join(HERE, "flexible_pendulum.csv")

# discretisations of (A)
MESH_DT = 2.5e-5                       # element study at this step
MESHES = (32, 64, 128, 256, 512)
STEP_NEL = 128                         # time-step study with this mesh
STEPS = (1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1.25e-5)
FINE = (512, 2.5e-5)                   # the reference run (CSV)
CHECK = (128, 2.5e-5)                  # where rho_inf = 1 and EA * 100 are run
EB_LIMIT = {"ga": GA * 1e3, "rho_i": RHO_I * 1e-3}
MODES = (1, 2, 4, 8, 12)               # mode study of (B)
N_MODES = 12                           # (B) compared with (A) in the Euler-Bernoulli limit
N_MODES_LIN = 8                        # (L), compared with (B) at the same number of modes


# ----------------------------------------------------------------------------- helpers
def refine_extremum(t, v, i):
    """Vertex of the parabola through samples i-1, i, i+1 (an extremum of sampled v)."""
    i = min(max(i, 1), len(v) - 2)
    vm, v0, vp = v[i - 1], v[i], v[i + 1]
    d2 = vm - 2.0 * v0 + vp
    if d2 == 0.0:
        return t[i], v0
    s = 0.5 * (vm - vp) / d2
    return t[i] + s * (t[i + 1] - t[i]), v0 - 0.125 * (vm - vp) ** 2 / d2


def extremes(t, v):
    """(t_max, v_max, t_min, v_min), parabola-refined, and the deepest local minima
    at least 0.02 s apart (t, v), deepest first."""
    tM, vM = refine_extremum(t, v, int(np.argmax(v)))
    tm, vm = refine_extremum(t, v, int(np.argmin(v)))
    dist = max(1, int(round(0.02 / (t[1] - t[0]))))
    pk, _ = find_peaks(-v, distance=dist)
    pk = pk[np.argsort(v[pk])][:3]
    mins = [refine_extremum(t, v, int(k)) for k in pk]
    return {"t_max": tM, "v_max": vM, "t_min": tm, "v_min": vm, "minima": mins}


def extremum_near(t, v, tc, kind, half=0.005):
    """(t, v) of the max (kind = 1) or min (kind = -1) of v within tc +- half, parabola-refined."""
    w = np.nonzero(np.abs(t - tc) <= half)[0]
    i = w[int(np.argmax(kind * v[w]))]
    return refine_extremum(t, v, int(i))


def at_times(t, y, times=TIMES):
    dt = t[1] - t[0]
    return np.array([y[int(round(tt / dt))] for tt in times])


# ----------------------------------------------------------------------------- (A) GE beam FE
def element_forces(q, le, ea=EA, ga=GA, ei=EI, tangent=True):
    """spin_up_beam.element_forces with the bending stiffness ei instead of spin_up_beam.EI.

    The bending part of that element is f_phi1 = -EI kap, f_phi2 = +EI kap, K_phiphi =
    EI/le [[1, -1], [-1, 1]] (kap = (phi2 - phi1)/le), linear in EI and uncoupled from the
    axial and shear parts, so the difference ei - spin_up_beam.EI is added here."""
    f, K = sub.element_forces(q, le, ga=ga, ea=ea, tangent=tangent)
    d = ei - sub.EI
    P = q[2::3]
    dm = d * (P[1:] - P[:-1]) / le
    f[:, 2] -= dm
    f[:, 5] += dm
    if tangent:
        kb = d / le
        K[:, 2, 2] += kb
        K[:, 5, 5] += kb
        K[:, 2, 5] -= kb
        K[:, 5, 2] -= kb
    return f, K


def check_element():
    """Max relative deviation of f from central differences of the energy and of K from central
    differences of f (random large deformation, this bar's section data)."""
    err_f, err_k = sub.check_tangent(forces=element_forces, ea=EA, ga=GA, ei=EI, le=0.25,
                                     amplitude=0.05, seed=3)
    q = np.zeros(15)
    q[0::3] = np.arange(5) * 0.25
    q += 0.05 * np.random.default_rng(3).standard_normal(q.size)
    le = 0.25
    # with ei = spin_up_beam.EI the function is spin_up_beam's element
    fa, Ka = element_forces(q, le, ei=sub.EI)
    fb, Kb = sub.element_forces(q, le, ga=GA, ea=EA)
    same = max(np.abs(fa - fb).max() / np.abs(fb).max(), np.abs(Ka - Kb).max() / np.abs(Kb).max())
    return err_f, err_k, same


def fe_setup(n_el, rho_i):
    """Banded consistent mass over the free DOFs (all but the root x, y), scatter indices."""
    le = L / n_el
    nd = 3 * (n_el + 1)
    nf = nd - 2                       # free DOFs: phi0, then (x, y, phi) of nodes 1..n_el
    ku = 5                            # half bandwidth
    md = np.array([RHO_A, RHO_A, rho_i])
    Me = np.zeros((6, 6))
    for i in range(2):
        for j in range(2):
            for d in range(3):
                Me[3 * i + d, 3 * j + d] = md[d] * le / 6.0 * (2.0 if i == j else 1.0)
    band_idx, ok, f_idx, f_ok = sub.band_pattern(n_el, nf, ku, 2)
    nb = (2 * ku + 1) * nf
    Mband = np.bincount(band_idx, np.broadcast_to(Me, (n_el, 6, 6))[ok], minlength=nb).reshape(2 * ku + 1, nf)
    return le, nd, nf, ku, Mband, band_idx, ok, f_idx, f_ok


def band_matvec(Mband, ku, x):
    out = np.zeros_like(x)
    n = len(x)
    for k in range(-ku, ku + 1):    # entry (i, j), i - j = k, is stored at [ku + k, j]
        row = Mband[ku + k]
        if k >= 0:
            out[k:] += row[:n - k] * x[:n - k]
        else:
            out[:n + k] += row[-k:] * x[-k:]
    return out


def run_fe(n_el, dt, t_end=T_END, rho_inf=RHO_INF, ea=EA, ga=GA, ei=EI, rho_i=RHO_I, tol=1e-12):
    """Model (A). Returns dict(t, phi (root section angle), v, u, tx, ty (tip), energy drift,
    newton = Newton iterations per step, wall)."""
    t0 = time.time()
    le, nd, nf, ku, Mband, band_idx, ok, f_idx, f_ok = fe_setup(n_el, rho_i)
    nb = (2 * ku + 1) * nf
    Fg = np.zeros(nd)
    Fg[1::3] = -RHO_A * G_ACC * le
    Fg[1] *= 0.5
    Fg[-2] *= 0.5
    Ff = Fg[2:]
    am, af, gm, beta, dq_da = sub.alpha_parameters(rho_inf, dt)
    q = np.zeros(nd)
    q[0::3] = np.arange(n_el + 1) * le
    v = np.zeros(nd)
    a = np.zeros(nd)
    a[2:] = solve_banded((ku, ku), Mband, Ff)     # undeformed: f_int = 0
    abar = a.copy()
    n_steps = int(round(t_end / dt))
    hist = np.empty((n_steps + 1, 3))
    hist[0] = (0.0, L, 0.0)
    every = max(1, int(round(CSV_STEP / dt)))

    def energy(q, v):
        f, _ = element_forces(q, le, ea, ga, ei, tangent=False)
        X, Y, P = q[0::3], q[1::3], q[2::3]
        dx, dy = np.diff(X) / le, np.diff(Y) / le
        pm = 0.5 * (P[1:] + P[:-1])
        e_ = np.cos(pm) * dx + np.sin(pm) * dy - 1.0
        g_ = -np.sin(pm) * dx + np.cos(pm) * dy
        k_ = np.diff(P) / le
        U = 0.5 * le * np.sum(ea * e_ * e_ + ga * g_ * g_ + ei * k_ * k_)
        T = 0.5 * v[2:] @ band_matvec(Mband, ku, v[2:])
        return T + U - Fg @ q

    E0 = energy(q, v)
    e_drift = 0.0
    iters = 0
    AB = np.zeros((3 * ku + 1, nf))
    for n in range(n_steps):
        q_hat = q + dt * v + dt * dt * (0.5 - beta) * abar
        v_hat = v + dt * (1.0 - gm) * abar
        abar_c = (af * a - am * abar) / (1.0 - am)
        a_new = a.copy()
        for it in range(30):
            ab_new = abar_c + (1.0 - af) / (1.0 - am) * a_new
            q_new = q_hat + dt * dt * beta * ab_new
            f, K = element_forces(q_new, le, ea, ga, ei, tangent=(it == 0))
            r = band_matvec(Mband, ku, a_new[2:]) + np.bincount(f_idx, f[f_ok], minlength=nf) - Ff
            if it == 0:
                AB[ku:] = Mband + dq_da * np.bincount(band_idx, K[ok], minlength=nb).reshape(2 * ku + 1, nf)
                lu, piv, info = dgbtrf(AB, ku, ku)
                assert info == 0, info
            da, info = dgbtrs(lu, ku, ku, -r, piv)
            a_new[2:] += da
            iters += 1
            if np.abs(da).max() * dq_da < tol:
                break
        else:
            raise RuntimeError("Newton did not converge at t = %g" % ((n + 1) * dt))
        ab_new = abar_c + (1.0 - af) / (1.0 - am) * a_new
        q = q_hat + dt * dt * beta * ab_new
        v = v_hat + dt * gm * ab_new
        a, abar = a_new, ab_new
        hist[n + 1] = (q[2], q[-3], q[-2])
        if (n + 1) % every == 0:
            e_drift = max(e_drift, abs(energy(q, v) - E0))
    ph, tx, ty = hist[:, 0], hist[:, 1], hist[:, 2]
    c, s = np.cos(ph), np.sin(ph)
    return {"t": dt * np.arange(n_steps + 1), "phi": ph, "v": -s * tx + c * ty, "u": c * tx + s * ty - L,
            "tx": tx, "ty": ty, "e_drift": e_drift, "newton": iters / n_steps, "wall": time.time() - t0,
            "n_el": n_el, "dt": dt}


def fe_frequencies(n_el, k=5, clamped=False):
    """Lowest k flexible frequencies [rad/s] of (A) linearised about the straight bar, without
    gravity: pinned at the root (x = y = 0; the pinned-free bending modes) or clamped (phi0 = 0
    too; the clamped-free modes, as in a Craig-Bampton basis clamped at the root face)."""
    le = L / n_el
    nd = 3 * (n_el + 1)
    q = np.zeros(nd)
    q[0::3] = np.arange(n_el + 1) * le
    _, Ke = element_forces(q, le)
    _, _, nf, ku, Mband, band_idx, ok, _, _ = fe_setup(n_el, RHO_I)
    Kb = np.bincount(band_idx, Ke[ok], minlength=(2 * ku + 1) * nf).reshape(2 * ku + 1, nf)

    def full(B):
        out = np.zeros((nf, nf))
        for d in range(-ku, ku + 1):
            j = np.arange(max(0, -d), min(nf, nf - d))
            out[j + d, j] = B[ku + d, j]
        return out

    # drop the axial x DOFs (uncoupled from bending in the straight state) and, clamped, phi0
    keep = [i for i in range(nf) if (i + 2) % 3 != 0 and not (clamped and i == 0)]
    Kf, Mf = full(Kb)[np.ix_(keep, keep)], full(Mband)[np.ix_(keep, keep)]
    w2 = eigh(Kf, Mf, eigvals_only=True, subset_by_index=[0, k - 1 if clamped else k])
    return np.sqrt(w2) if clamped else np.sqrt(np.abs(w2[1:]))   # pinned: w2[0] ~ 0, the rotation


# ----------------------------------------------------------------------------- (B), (L), (R)
def modes(n, x):
    """Cantilever modes phi_i(x), phi_i'(x) of length L (int phi^2 = L) and beta_i L.
    spin_up_beam.cantilever_modes is for its L = 10 m; phi depends on x/L only."""
    s = sub.L / L
    bl, phi, dphi = sub.cantilever_modes(n, np.asarray(x, dtype=float) * s)
    return bl, phi, dphi * s


def modal_matrices(n, panels=8, points=100):
    g, w = np.polynomial.legendre.leggauss(points)
    h = L / panels
    x = np.concatenate([(p + 0.5 * (g + 1.0)) * h for p in range(panels)])
    wq = np.tile(0.5 * h * w, panels)
    bl, phi, dphi = modes(n, x)
    mats = {
        "M": RHO_A * (phi * wq) @ phi.T,
        "K": np.diag(EI * (bl / L) ** 4 * L),
        "KG": (dphi * (wq * 0.5 * RHO_A * (L * L - x * x))) @ dphi.T,
        "KGg": (dphi * (wq * RHO_A * (L - x))) @ dphi.T,
        "Ku": (dphi * wq) @ dphi.T,
        "b": RHO_A * (phi * wq) @ x,
        "c": RHO_A * (phi * wq).sum(axis=1),
        "phiL": modes(n, np.array([L]))[1][:, 0],
        "bl": bl,
    }
    return mats


def run_modal(n, stiffening=True, t_end=T_END, rtol=1e-10, atol=1e-10, sample=2.5e-5):
    """Model (B) (stiffening=True) or (L), sampled every `sample` s. Returns dict(t, phi, phid
    (= theta'), v, u, tx, ty, energy drift, nfev, wall)."""
    t0 = time.time()
    mt = modal_matrices(n)
    M, K, b, c = mt["M"], mt["K"], mt["b"], mt["c"]
    KG = mt["KG"] if stiffening else np.zeros_like(M)
    KGg = mt["KGg"] if stiffening else np.zeros_like(M)
    Ms = M - KG
    J = RHO_A * L**3 / 3.0
    S = RHO_A * L * L / 2.0
    g = G_ACC

    m0 = M[0, 0]                      # M = rho A L I (asserted in main)
    kd = np.diag(K).copy()
    bb = b @ b / m0

    def rhs(t, y):
        # M diagonal: q'' = (f_q - b theta'')/m0, theta'' from the Schur complement
        th, q, thd, qd = y[0], y[1:n + 1], y[n + 1], y[n + 2:]
        st, ct = math.sin(th), math.cos(th)
        Msq = Ms @ q
        KGgq = KGg @ q
        f_th = -2.0 * thd * (qd @ Msq) - g * ct * (S - 0.5 * (q @ KGgq)) + g * st * (c @ q)
        f_q = thd * thd * Msq - kd * q + g * st * KGgq - g * ct * c
        thdd = (f_th - (b @ f_q) / m0) / (J + q @ Msq - bb)
        out = np.empty_like(y)
        out[0] = thd
        out[1:n + 1] = qd
        out[n + 1] = thdd
        out[n + 2:] = (f_q - b * thdd) / m0
        return out

    def energy(y):
        th, q, thd, qd = y[0], y[1:n + 1], y[n + 1], y[n + 2:]
        T = 0.5 * thd * thd * (J + q @ Ms @ q) + thd * (b @ qd) + 0.5 * qd @ M @ qd
        V = 0.5 * q @ K @ q + g * math.sin(th) * (S - 0.5 * q @ KGg @ q) + g * math.cos(th) * (c @ q)
        return T + V

    sol = solve_ivp(rhs, (0.0, t_end), np.zeros(2 * n + 2), method="DOP853", rtol=rtol, atol=atol,
                    dense_output=True)
    assert sol.success, sol.message
    t = np.linspace(0.0, t_end, int(round(t_end / sample)) + 1)
    Y = sol.sol(t)
    e0 = energy(Y[:, 0])
    e_drift = max(abs(energy(Y[:, k]) - e0) for k in range(0, len(t), int(round(CSV_STEP / sample))))
    Ku = mt["Ku"] if stiffening else np.zeros_like(M)
    th, q, thd = Y[0], Y[1:n + 1], Y[n + 1]
    v = mt["phiL"] @ q
    u = -0.5 * np.einsum("it,ij,jt->t", q, Ku, q)
    ct, st = np.cos(th), np.sin(th)
    return {"t": t, "phi": th, "phid": thd, "v": v, "u": u, "tx": ct * (L + u) - st * v,
            "ty": st * (L + u) + ct * v, "n": n, "e_drift": e_drift, "nfev": sol.nfev,
            "wall": time.time() - t0}


def rigid(J):
    """Rigid pendulum theta(t) (dense), J theta'' = -m g (L/2) cos(theta), and its half period
    from the elliptic integral (time from theta = 0 to the turning point theta = -pi)."""
    k = MASS * G_ACC * 0.5 * L / J
    sol = solve_ivp(lambda t, y: [y[1], -k * math.cos(y[0])], (0.0, 1.2), [0.0, 0.0], method="DOP853",
                    rtol=1e-12, atol=1e-14, dense_output=True)
    # released at 90 degrees from hanging: period 4 sqrt(J/(m g d)) K(1/2)
    half = 2.0 * math.sqrt(1.0 / k) * ellipk(0.5)
    return sol, half


def pinned_free_roots(n):
    """beta_i L of the pinned-free Euler-Bernoulli beam: roots of tan x = tanh x, x > 0."""
    f = lambda x: math.sin(x) * math.cosh(x) - math.cos(x) * math.sinh(x)
    return np.array([brentq(f, (k + 1.25) * math.pi - 0.3, (k + 1.25) * math.pi + 0.3, xtol=1e-14)
                     for k in range(n)])


def pinned_free_southwell(n):
    """First flexible mode of the modal model with the frame angle free (pinned-free), and the
    first-order changes of its omega^2: with the mode vector z (mass-normalised),
    d omega^2/d Omega^2 = z^T (K_G - M) z for (B), z^T (-M) z for (L) (steady spin), and
    d omega^2/d g_a = z^T K_Gg z (axial gravity g_a = -g sin(theta), tension towards the pin)."""
    mt = modal_matrices(n)
    Mf = np.zeros((n + 1, n + 1))
    Mf[0, 0] = RHO_A * L**3 / 3.0
    Mf[0, 1:] = Mf[1:, 0] = mt["b"]
    Mf[1:, 1:] = mt["M"]
    Kf = np.zeros_like(Mf)
    Kf[1:, 1:] = mt["K"]
    w2, Z = eigh(Kf, Mf)
    z = Z[1:, 1]          # Z[:, 0] is the rigid rotation about the pin

    def quad(A_):
        return float(z @ A_ @ z)

    return {"w2": w2[1], "c": quad(mt["KG"] - mt["M"]), "c_lin": quad(-mt["M"]), "g": quad(mt["KGg"])}


def time_shift(t, a, b, tc, half=0.04, span=0.015):
    """tau minimising the rms of a(t) - b(t - tau) over |t - tc| <= half (tau > 0: a lags b)."""
    w = (t >= tc - half) & (t <= tc + half)
    tw, aw = t[w], a[w]
    cost = lambda tau: np.mean((aw - np.interp(tw - tau, t, b)) ** 2)
    grid = np.linspace(-span, span, 601)
    k = int(np.argmin([cost(x) for x in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    r = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-9})
    return r.x, math.sqrt(r.fun)


# ----------------------------------------------------------------------------- report
def _task(task):
    key, kind, kw = task
    if kind == "fe":
        return key, run_fe(**kw)
    return key, run_modal(**kw)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                    help="runs in parallel (default min(2, CPUs))")
    args = ap.parse_args()
    t_start = time.time()

    def say(s=""):
        print(s, flush=True)

    # ---- data, derived numbers
    omega1_c = sub.cantilever_roots(1)[0] ** 2 * math.sqrt(EI / (RHO_A * L**4))
    say("Flexible pendulum: L = %g m, h = b = %g m, E = %g Pa, nu = %g, rho = %g kg/m^3, g = %g m/s^2"
        % (L, H, E, NU, RHO, G_ACC))
    say("   EA = %.6g N, EI = %.6g N m^2, GA = (5/6) G A = %.6g N, rho A = %.6g kg/m, rho I = %.6g kg m,"
        " m = %.6g kg" % (EA, EI, GA, RHO_A, RHO_I, MASS))
    J_R = RHO_A * L**3 / 3.0 + RHO_I * L
    om_bot = math.sqrt(MASS * G_ACC * L / J_R)        # rigid: (1/2) J W^2 = m g L/2
    say("   clamped-free omega_1 = %.4f rad/s; rigid swing rate at the bottom Omega = %.4f rad/s,"
        " Omega^2/omega_1^2 = %.4f" % (omega1_c, om_bot, om_bot**2 / omega1_c**2))
    say()

    # ---- checks
    err_f, err_k, same = check_element()
    assert err_f < 1e-6 and err_k < 1e-6 and same < 1e-14, (err_f, err_k, same)
    say("Checks: element force vs d(energy), tangent vs d(force) (central differences): %.1e, %.1e;"
        % (err_f, err_k))
    say("        element with ei = spin_up_beam.EI vs spin_up_beam.element_forces: %.1e" % same)
    mt = modal_matrices(N_MODES)
    orth = np.abs(mt["M"] / (RHO_A * L) - np.eye(N_MODES)).max()
    assert orth < 1e-9, orth      # run_modal uses M = rho A L I
    sw, swg = mt["KG"][0, 0] / mt["M"][0, 0], mt["KGg"][0, 0] / mt["M"][0, 0]
    say("        cantilever modes: |M/(rho A L) - I| = %.1e (%d modes); K_G11/M11 = %.4f (Southwell),"
        " K_Gg11/M11 = %.4f 1/m" % (orth, N_MODES, sw, swg))
    st = om_bot**2 * (sw - 1.0) + G_ACC * swg
    say("        clamped mode 1 at the bottom of the swing, one mode: omega^2 = omega_1^2 + Omega^2 (K_G11/M11 - 1)"
        " + g K_Gg11/M11")
    say("        = omega_1^2 (1 %+.2f %%); the linear model: omega_1^2 - Omega^2 = omega_1^2 (1 %+.2f %%)"
        % (100 * st / omega1_c**2, -100 * om_bot**2 / omega1_c**2))
    lam = pinned_free_southwell(N_MODES)
    w0 = math.sqrt(lam["w2"])
    say("        pinned-free mode 1 (%d cantilever modes + free frame angle): omega = %.4f rad/s;"
        " d omega^2/d Omega^2 = %.3f (B), %.3f (L);" % (N_MODES, w0, lam["c"], lam["c_lin"]))
    say("        d omega^2/d g_axial = %.3f 1/m (B, tension by the gravity component along the bar), 0 (L)"
        % lam["g"])
    sh_b = (lam["c"] * om_bot**2 + lam["g"] * G_ACC) / lam["w2"]
    sh_l = lam["c_lin"] * om_bot**2 / lam["w2"]
    say("        at the bottom of the swing: omega^2 (1 %+.3f %%) (B), omega^2 (1 %+.3f %%) (L); frequency"
        " ratio (B)/(L) - 1 = %.3f %%" % (100 * sh_b, 100 * sh_l, 100 * (math.sqrt((1 + sh_b) / (1 + sh_l)) - 1)))
    sol_r, half = rigid(J_R)
    th_half = sol_r.sol(half)[0]
    assert abs(th_half + math.pi) < 1e-8 and abs(sol_r.sol(half)[1]) < 1e-7, th_half
    say("        rigid pendulum: theta(T/2) + pi = %.1e at T/2 = 2 sqrt(J/(m g L/2)) K(1/2) = %.6f s"
        % (th_half + math.pi, half))
    say()

    # ---- pinned-free frequencies
    w_eb = pinned_free_roots(5) ** 2 * math.sqrt(EI / (RHO_A * L**4))
    say("Pinned-free bending frequencies [rad/s] of (A), linearised about the straight bar, no gravity:")
    say("   %8s %s" % ("n_el", " ".join("%11s" % ("mode %d" % (k + 1)) for k in range(5))))
    wf = {}
    for n_el in (64, 128, 256, 512):
        wf[n_el] = fe_frequencies(n_el)
        say("   %8d %s" % (n_el, " ".join("%11.4f" % x for x in wf[n_el])))
    w_ex = wf[512] + (wf[512] - wf[256]) / 3.0
    say("   %8s %s" % ("Richard.", " ".join("%11.4f" % x for x in w_ex)))
    say("   %8s %s   (tan x = tanh x)" % ("EB exact", " ".join("%11.4f" % x for x in w_eb)))
    say("   phase error (w(n) - w_inf) * 1 s [rad]: n = 256: %s; n = 512: %s" % (
        " ".join("%.3f" % x for x in wf[256] - w_ex), " ".join("%.3f" % x for x in wf[512] - w_ex)))
    say("   shear + rotary inertia: (A)/EB - 1 = %s" % " ".join("%+.2e" % x for x in w_ex / w_eb - 1.0))
    wc = {n_el: fe_frequencies(n_el, clamped=True) for n_el in (256, 512)}
    wc_ex = wc[512] + (wc[512] - wc[256]) / 3.0
    wc_eb = sub.cantilever_roots(5) ** 2 * math.sqrt(EI / (RHO_A * L**4))
    say("Clamped-free (Craig-Bampton fixed-interface) frequencies [rad/s]: (A) Richardson 256/512 el.: %s"
        % " ".join("%.4f" % x for x in wc_ex))
    say("   Euler-Bernoulli: %s; (A)/EB - 1 = %s" % (" ".join("%.4f" % x for x in wc_eb), " ".join(
        "%+.2e" % x for x in wc_ex / wc_eb - 1.0)))
    say()

    # ---- all runs, in parallel
    tasks = []
    for n_el in MESHES:
        tasks.append(((n_el, MESH_DT, "ref"), "fe", {"n_el": n_el, "dt": MESH_DT}))
    for dt in STEPS:
        if (STEP_NEL, dt) != (STEP_NEL, MESH_DT):
            tasks.append(((STEP_NEL, dt, "ref"), "fe", {"n_el": STEP_NEL, "dt": dt}))
    tasks.append((CHECK + ("rho1",), "fe", {"n_el": CHECK[0], "dt": CHECK[1], "rho_inf": 1.0}))
    tasks.append((CHECK + ("ea100",), "fe", {"n_el": CHECK[0], "dt": CHECK[1], "ea": 100 * EA}))
    tasks.append((FINE + ("eb",), "fe", dict(n_el=FINE[0], dt=FINE[1], **EB_LIMIT)))
    for n in MODES:
        tasks.append((("B", n), "modal", {"n": n, "stiffening": True}))
    tasks.append((("L", N_MODES_LIN), "modal", {"n": N_MODES_LIN, "stiffening": False}))
    cost = lambda tk: (tk[2]["n_el"] / tk[2]["dt"] * 1.4e-8 + 4.0) if tk[1] == "fe" else 2.5 * tk[2]["n"] ** 1.5
    tasks.sort(key=lambda tk: -cost(tk))
    t_runs = time.time()
    if args.jobs > 1:
        with Pool(args.jobs) as pool:
            runs = dict(pool.imap_unordered(_task, tasks))
    else:
        runs = dict(map(_task, tasks))
    say("%d runs in %.0f s wall (%d jobs), %.0f s CPU in the runs" % (
        len(runs), time.time() - t_runs, args.jobs, sum(r["wall"] for r in runs.values())))
    for r in runs.values():
        r["at"] = at_times(r["t"], r["v"])
        r["phi_at"] = at_times(r["t"], r["phi"])
        r["ext"] = extremes(r["t"], r["v"])
    say()

    # ---- convergence of (A)
    def row(label, r, prev=None):
        x = r["ext"]
        say("   %-17s %s   %9.5f %7.4f %9.5f %7.4f %5.2f %5.1f" % (
            label, " ".join("%9.5f" % (1e3 * y) for y in r["at"]), 1e3 * x["v_max"], x["t_max"],
            1e3 * x["v_min"], x["t_min"], r["newton"], r["wall"]))
        if prev is not None:
            say("   %-17s %s   %9.5f %7s %9.5f" % ("  change", " ".join("%9.5f" % (1e3 * y) for y in r["at"] - prev["at"]),
                1e3 * (x["v_max"] - prev["ext"]["v_max"]), "", 1e3 * (x["v_min"] - prev["ext"]["v_min"])))

    head = "   %-17s %s   %9s %7s %9s %7s %5s %5s" % (
        "run", " ".join("%9s" % ("v(%g)" % t) for t in TIMES), "v_max", "t_max", "v_min", "t_min", "Newt", "wall")
    say("(A) convergence, rho_inf = %g: v_transverse [mm] at t [s], its extremes [mm] and their times [s]" % RHO_INF)
    say(head)
    prev = None
    for n_el in MESHES:
        r = runs[(n_el, MESH_DT, "ref")]
        row("n=%d dt=%g" % (n_el, MESH_DT), r, prev)
        prev = r
    say(head)
    prev = None
    for dt in STEPS:
        r = runs[(STEP_NEL, dt, "ref")]
        row("n=%d dt=%g" % (STEP_NEL, dt), r, prev)
        prev = r
    say("   phi0 [rad] at t:")
    for key in [(n, MESH_DT, "ref") for n in MESHES[-3:]] + [(STEP_NEL, dt, "ref") for dt in STEPS[-2:]]:
        say("   %-17s %s" % ("n=%d dt=%g" % key[:2], " ".join("%13.9f" % y for y in runs[key]["phi_at"])))
    say()

    fine = runs[FINE + ("ref",)]
    mid = runs[(MESHES[-2], MESH_DT, "ref")]
    t_a = runs[(STEP_NEL, STEPS[-2], "ref")]
    t_b = runs[(STEP_NEL, STEPS[-1], "ref")]
    err_v = np.abs(fine["at"] - mid["at"]) + np.abs(t_b["at"] - t_a["at"])
    err_phi = np.abs(fine["phi_at"] - mid["phi_at"]) + np.abs(t_b["phi_at"] - t_a["phi_at"])
    err_curve = (np.abs(fine["v"] - mid["v"]).max()
                 + np.abs(t_b["v"][::int(round(STEPS[-2] / STEPS[-1]))] - t_a["v"]).max())
    ext_err = {}      # the same extremum (the one of the reference run) in each run
    for kk, sign in (("max", 1), ("min", -1)):
        tc = fine["ext"]["t_" + kk]
        e = [extremum_near(r["t"], r["v"], tc, sign) for r in (fine, mid, t_a, t_b)]
        ext_err["v_" + kk] = abs(e[0][1] - e[1][1]) + abs(e[3][1] - e[2][1])
        ext_err["t_" + kk] = abs(e[0][0] - e[1][0]) + abs(e[3][0] - e[2][0])

    # ---- rho_inf, EA, energy
    base = runs[CHECK + ("ref",)]
    for key, label in (("rho1", "rho_inf = 1.0 instead of %g" % RHO_INF), ("ea100", "EA * 100 (axial modes 10x stiffer)")):
        r = runs[CHECK + (key,)]
        say("(A) n = %d, dt = %g, %-36s: v changes by %.1e m at the 4 times, %.1e m max over 0..1 s"
            % (CHECK[0], CHECK[1], label, np.abs(r["at"] - base["at"]).max(), np.abs(r["v"] - base["v"]).max()))
    say("    energy T + U + V_g: max |E(t) - E(0)| = %.1e J (rho_inf = %g), %.1e J (rho_inf = 1); m g L/2 = %.3f J"
        % (base["e_drift"], RHO_INF, runs[CHECK + ("rho1",)]["e_drift"], 0.5 * MASS * G_ACC * L))
    say()

    # ---- reference values
    say("Reference (A): n = %d, dt = %g (the CSV run). Error estimate = |v(n %d) - v(n %d)| at dt %g"
        % (FINE[0], FINE[1], MESHES[-1], MESHES[-2], MESH_DT))
    say("   + |v(dt %g) - v(dt %g)| at n %d (plain differences; the convergence is about first order)"
        % (STEPS[-2], STEPS[-1], STEP_NEL))
    say("   %6s %16s %9s %15s %9s %12s %12s %12s" % ("t [s]", "v_transverse [m]", "+-", "phi0 [rad]", "+-",
                                                    "u_axial [m]", "tip x [m]", "tip y [m]"))
    ua, txa, tya = (at_times(fine["t"], fine[k]) for k in ("u", "tx", "ty"))
    for k, tt in enumerate(TIMES):
        say("   %6g %16.6e %9.1e %15.8f %9.1e %12.4e %12.7f %12.7f" % (
            tt, fine["at"][k], err_v[k], fine["phi_at"][k], err_phi[k], ua[k], txa[k], tya[k]))
    x = fine["ext"]
    say("   v_max = %.6e m +- %.1e at t = %.5f s +- %.1e (the first overshoot)" % (
        x["v_max"], ext_err["v_max"], x["t_max"], ext_err["t_max"]))
    say("   v_min = %.6e m +- %.1e at t = %.5f s +- %.1e" % (x["v_min"], ext_err["v_min"], x["t_min"], ext_err["t_min"]))
    say("   the three deepest minima (>= 0.02 s apart): %s" % ", ".join(
        "%.5e m at %.4f s" % (vv, tt) for tt, vv in x["minima"]))
    say("   curve: max over 0..1 s of the same error estimate %.1e m; max |v| = %.4e m" % (
        err_curve, np.abs(fine["v"]).max()))
    say()

    # ---- rigid pendulum
    th_r = sol_r.sol(fine["t"])[0]
    dphi = fine["phi"] - th_r
    say("(R) rigid pendulum (J = rho A L^3/3 + rho I L): theta at t: %s rad" % " ".join(
        "%.8f" % y for y in sol_r.sol(np.array(TIMES))[0]))
    say("    phi0 (A) - theta: %s rad at t; max |.| over 0..1 s = %.2e rad" % (
        " ".join("%+.2e" % y for y in at_times(fine["t"], dphi)), np.abs(dphi).max()))
    say()

    # ---- modal models
    say("(B) stiffened and (L) linear floating frame, cantilever modes, DOP853 rtol 1e-10: v [mm]")
    say("   %-5s %5s %s   %9s %7s %9s %7s %8s %5s" % ("model", "modes", " ".join(
        "%9s" % ("v(%g)" % t) for t in TIMES), "v_max", "t_max", "v_min", "t_min", "dE [J]", "wall"))
    for key in [("B", n) for n in MODES] + [("L", N_MODES_LIN)]:
        o = runs[key]
        assert o["e_drift"] < 1e-9, (key, o["e_drift"])
        say("   %-5s %5d %s   %9.5f %7.4f %9.5f %7.4f %8.1e %5.1f" % (
            key[0], key[1], " ".join("%9.5f" % (1e3 * y) for y in o["at"]), 1e3 * o["ext"]["v_max"],
            o["ext"]["t_max"], 1e3 * o["ext"]["v_min"], o["ext"]["t_min"], o["e_drift"], o["wall"]))
    d_mode = np.abs(runs[("B", MODES[-1])]["v"] - runs[("B", MODES[-2])]["v"]).max()
    say("   (B) %d vs %d modes: max |dv| over 0..1 s = %.1e m" % (MODES[-1], MODES[-2], d_mode))
    say()

    B = runs[("B", N_MODES)]
    B8 = runs[("B", N_MODES_LIN)]
    Lm = runs[("L", N_MODES_LIN)]
    eb = runs[FINE + ("eb",)]
    amp = np.abs(fine["v"]).max()
    wins = (0.1, 0.25, 0.5, 1.0)
    say("Model differences in v_transverse [mm] at t, and max |difference| [m] over 0..t_w:")
    say("   %-38s %s  %s" % ("", " ".join("%9s" % ("t=%g" % t) for t in TIMES), " ".join(
        "%9s" % ("0..%g" % t) for t in wins)))
    for label, r in (("(A) reference", fine), ("(A) EB limit, n %d" % FINE[0], eb), ("(B) %d modes" % N_MODES, B),
                     ("(L) %d modes" % N_MODES_LIN, Lm)):
        say("   %-38s %s" % (label, " ".join("%9.5f" % (1e3 * y) for y in r["at"])))
    diffs = {}
    for key, label, a, b in (("ebB", "(A) EB limit n %d - (B) %d" % (FINE[0], N_MODES), eb, B),
                             ("shear", "(A) - (A) EB limit: shear, rho I", fine, eb),
                             ("stiff", "(B) - (L), %d modes: stiffening" % N_MODES_LIN, B8, Lm),
                             ("AB", "(A) - (B)", fine, B),
                             ("AL", "(A) - (L): error of linear FFRF", fine, Lm)):
        d = a["v"] - b["v"]
        mx = [np.abs(d[fine["t"] <= tw + 1e-12]).max() for tw in wins]
        diffs[key] = mx
        say("   %-38s %s  %s" % (label, " ".join("%9.5f" % (1e3 * y) for y in a["at"] - b["at"]),
                                  " ".join("%9.2e" % y for y in mx)))
    say("   (for scale: max |v| = %.3e m; the error estimate of (A) over the curve is %.1e m)" % (amp, err_curve))
    say("   extremes [mm] (max / min): (A) %.5f / %.5f, (A) EB %.5f / %.5f, (B) %.5f / %.5f, (L) %.5f / %.5f"
        % tuple(1e3 * z for r in (fine, eb, B, Lm) for z in (r["ext"]["v_max"], r["ext"]["v_min"])))
    say("   time shift tau of the oscillation, a(t) ~ b(t - tau), fitted over t_c +- 0.04 s [ms]:")
    say("   %-38s %s" % ("", " ".join("%9s" % ("t_c=%g" % t) for t in (0.25, 0.5, 0.75, 0.95))))
    for label, a, b in (("(A) - (L)", fine, Lm), ("(B) - (L)", B8, Lm), ("(A) - (A) EB limit", fine, eb),
                        ("(A) EB limit - (B)", eb, B), ("(A) n %d - n %d" % (FINE[0], MESHES[-2]), fine, mid)):
        say("   %-38s %s" % (label, " ".join("%9.4f" % (1e3 * time_shift(fine["t"], a["v"], b["v"], tc)[0])
                                           for tc in (0.25, 0.5, 0.75, 0.95))))
    say("   phi0 at t [rad]: (L) - (A) %s; (A) - (A) EB limit %s; (B) - (A) EB limit %s" % tuple(
        " ".join("%+.1e" % y for y in d) for d in (Lm["phi_at"] - fine["phi_at"], fine["phi_at"] - eb["phi_at"],
                                                   B["phi_at"] - eb["phi_at"])))
    # axial: (A) EB limit = (B) foreshortening + quasi-static stretch of the rod
    st_ = (RHO_A / EA) * (B["phid"] ** 2 * L**3 / 3.0 - G_ACC * np.sin(B["phi"]) * L * L / 2.0)
    du = eb["u"] - (B["u"] + st_)
    say("   u_axial: (A) EB limit vs (B) foreshortening + quasi-static stretch rho A/EA (Omega^2 L^3/3"
        " - g sin(phi0) L^2/2):")
    say("      max |difference| %.1e m, max |u| %.1e m, max stretch %.1e m" % (
        np.abs(du).max(), np.abs(eb["u"]).max(), np.abs(st_).max()))
    rel = diffs["ebB"][-1] / amp
    assert rel < 0.02, rel
    assert np.abs(du).max() < 0.05 * np.abs(eb["u"]).max(), np.abs(du).max()
    say()

    # ---- CSV
    k = int(round(CSV_STEP / FINE[1]))
    with open(CSV_PATH, "w") as fh:
        fh.write("t_s,phi0_rad,v_transverse_m,u_axial_m,tip_x_m,tip_y_m\n")
        for i in range(0, len(fine["t"]), k):
            fh.write("%.3f,%.10e,%.7e,%.7e,%.10e,%.10e\n" % (fine["t"][i], fine["phi"][i], fine["v"][i],
                                                             fine["u"][i], fine["tx"][i], fine["ty"][i]))
    say("Wrote %s (%d rows): model (A), %d elements, dt = %g s, every %g s" % (
        os.path.relpath(CSV_PATH), len(range(0, len(fine["t"]), k)), FINE[0], FINE[1], CSV_STEP))
    ru = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    say("Total run time %.0f s wall, %.0f s CPU (%d jobs)" % (time.time() - t_start,
        sum(r.ru_utime + r.ru_stime for r in ru), args.jobs))


if __name__ == "__main__":
    main()
