#!/usr/bin/python3
"""Geometrically nonlinear reference for the rod of Simeon's flexible slider-crank.

Purpose. slider_crank.py integrates the published model (Simeon 1996, the IVP test set's "crank"):
a linear elastic rod in the frame of its chord (floating frame). This script computes the same
motion with a geometrically exact model of the rod that shares nothing with it (no modes, no
floating frame): planar co-rotational Euler-Bernoulli beam elements in the inertial frame, so that
the effect of the rod's axial force on its bending (P-delta) and all large-rotation terms are in.

Problem (Simeon 1996; the values of slider_crank.py). Crank L1 = 0.15 m, rigid, driven at
phi1 = 150 t. Rod L2 = 0.30 m, steel, square section H = 8 mm: E = 2.0e11 Pa, rho = 7870 kg/m^3,
A = H^2 = 6.4e-5 m^2, I = H^4/12. Slider: point mass m3 = 0.075552 kg on the x axis. No gravity,
no damping. The crank's inertia does not matter here: the crank pin's motion is prescribed.

Rod model: co-rotational beam (Crisfield 1991, vol. 1, ch. 7: the 2D co-rotational element
with a linear local element). Nodes k = 0..n (n elements of length l0 = L2/n), DOFs
(x_k, y_k, theta_k), theta the section rotation from the initial (straight, along +x) state. For
an element with end nodes 1, 2:
    l = |x2 - x1|,  c = (x2 - x1)/l,  s = (y2 - y1)/l,  beta = atan2(y2 - y1, x2 - x1),
    u_l = l - l0,  th1 = theta1 - (beta - beta0),  th2 = theta2 - (beta - beta0),  beta0 = 0,
    N = EA u_l / l0,  M1 = EI/l0 (4 th1 + 2 th2),  M2 = EI/l0 (2 th1 + 4 th2),
    f_int = B^T [N, M1, M2],  with the exact B = d(u_l, th1, th2)/d(x1, y1, theta1, x2, y2, theta2):
        r = [-c, -s, 0, c, s, 0],  z = [s, -c, 0, -s, c, 0],
        B = [r;  [0, 0, 1, 0, 0, 0] - z/l;  [0, 0, 0, 0, 0, 1] - z/l],
    i.e. f_int = N r - (M1 + M2)/l z + M1 e3 + M2 e6. f_int is the gradient of the element's strain
    energy EA u_l^2/(2 l0) + EI/(2 l0) (4 th1^2 + 4 th1 th2 + 4 th2^2) (no approximation of the
    rigid rotation: exact for large rotations; the axial force acts on the rotated chords, which is
    the P-delta effect). With small strains the element converges to the geometrically exact
    (Kirchhoff) rod as l0 -> 0. The rod angle stays within +-pi/2, so atan2 needs no unwrapping.
Mass: lumped, per element rho A l0/2 on each node's x and y and rho I l0/2 on each node's theta
(the rotary inertia of the section, which the published model leaves out; its effect on the first
bending frequency is (pi r/L2)^2/2 = 3e-4, r^2 = I/A),
plus m3 on the last node's x. It converges to the continuum mass as the mesh is refined.
Boundary conditions: node 0 at the crank pin, (x0, y0) = L1 (cos 150 t, sin 150 t) prescribed,
theta0 free (pin); node n on the slider: y_n = 0 prescribed, x_n and theta_n free.
Equations of motion of the free DOFs:  M a = -f_int(q).

Initial values: the published ones (Y0 of slider_crank.py; cases/slider_crank_flexible/case.yaml).
At t = 0 phi1 = phi2 = 0; material point X in [0, L2], s = X/L2, sits at
    x = L1 + X + u(X),  y = 0,  theta = w'(X) = 0,   u = q3 N_m + q4 N_e,  N_m = 4 s (1 - s),
    N_e = s (2 s - 1),  q3 = 1.03339863e-5, q4 = 1.69327969e-5,
with the velocities (chord frame turning at phi2' about the crank pin, which moves at (0, 22.5)):
    v = (0, 22.5) + phi2' e_z x (X + u, 0) + (u_dot, w_dot),   theta_dot = phi2' + w_dot'(X),
    w_dot = q1' sin(pi s) + q2' sin(2 pi s),  u_dot = q3' N_m + q4' N_e,
    phi2' = -74.9957670, q1' = 0.444896105, q2' = 0.00463434311, q3' = -1.78591076e-6,
    q4' = -2.68938672e-6.  phi2' = -L1 150 / (L2 + q4) makes the slider's y velocity zero.
For the stiffness scaling test (E -> k E) all elastic initial values are divided by k (and phi2',
x3 recomputed from the constraints), the same in both models, so that the start stays close to
the smooth motion of the stiffer rod.

Time integration: central differences (leapfrog / velocity Verlet; explicit, second order, no
numerical damping), step 0.8 x 2/omega_max, omega_max the highest frequency of the linearized
system at t = 0 (numpy eigvalsh of M^-1/2 K M^-1/2, K from central differences of f_int),
rounded down to divide the output interval 1e-4 s.

Output: q1(t), the signed distance of the rod's middle node from the line through its end nodes,
positive along e_z x (chord direction) (as chord_deflection() in tests/check_slider_crank_acf.py;
the published q1 is the lateral chord-frame coordinate of the half-sine, whose value at the
mid-point is the mid-point deflection since the full sine vanishes there), every 1e-4 s to 0.1 s,
and the slider position x3(0.1) (published 0.1697373326718410).

What it prints:
  1. mesh (16, 32, 64 elements) and time-step (halved, 64 elements) convergence of the q1 history
     and x3(0.1); the 64-element run is the reference of 3. and 4.;
  2. the linear limit: beam (32 elements) and linear Galerkin model (slider_crank.py) with E scaled
     by k = 1, 10, 100: max |q1_beam - q1_lin| / max |q1_lin| shrinks like 1/k to the models' small
     difference, for the mid-node deflection and for the beam's half-sine coefficient (which has no
     truncation error of the two-sine Galerkin model);
  3. the ACF and FFRF histories of flexopt (`--histories`, default /tmp/sc/histories.json, if it
     exists) against the beam: max |diff| / max |beam|, amplitudes, q1(0.1);
  4. the test set's nonlinear coupling (slider_crank.py nonlinear=True) against the beam, and two
     corrections of it that locate its error (coupling_force, checked to reproduce
     slider_crank.coupling to round-off):
     - the test set's term is the gradient of the cubic part EA/2 int u' w'^2 dx of the von Karman
       membrane energy EA/2 int (u' + w'^2/2)^2 dx only. Its lateral force EA int u' w' dw' uses
       EA u' as the axial force, but the axial equations (whose coupling term is right) make
       EA u' = N - EA P(w'^2/2), P the projection onto the axial strain space (linear in x): for
       the half-sine, -EA (pi q1/L2)^2/4, a spurious compression. It softens the first bending
       mode by the factor 1 - A q1^2/(4 I) = 1 - 3 q1^2/H^2 (-12 % at q1 = 1.6 mm, -25 % at
       2.3 mm), hence the large amplitude. The quartic term EA/8 int w'^4 cancels it;
     - with it ("complete von Karman"), the membrane strain u' + w'^2/2 keeps the part of w'^2/2
       the quadratic axial field cannot follow, (pi q1/L2)^2 cos(2 pi x/L2)/4: membrane locking,
       stiffening by 1 + 3 q1^2/(2 H^2) (+6 % at 1.6 mm);
     - projecting w'^2/2 onto the axial strain space ("assumed membrane strain") removes the
       locking: lateral force int N w' dw' with the Galerkin axial force N, i.e. the P-delta
       effect alone. Also run with the consistent axial mass (the test set's is 15 times it).

Sources: M. A. Crisfield, Non-linear Finite Element Analysis of Solids and Structures, vol. 1,
Wiley 1991, ch. 7 (co-rotational beam); B. Simeon, Modelling a flexible slider crank mechanism by
a mixed system of DAEs and PDEs, Math. Modelling of Systems 2 (1996) 1-18; its model as the IVP
test set's problem "crank" (Lioen & de Swart; Mazzia & Magherini), in slider_crank.py.

Usage: scripts/reference/slider_crank_beam.py [--histories FILE] [--quick] [--jobs N]
  about 2.5 min on two loaded cores (N = 2 worker processes by default);
  --quick: only the 32-element beam and the Galerkin model at k = 1, linear and assumed strain.
"""
import argparse
import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")    # tiny matrices: threads only compete with the worker processes
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import slider_crank as sc  # noqa: E402

L1, L2, M3, OMEGA, RHO = sc.L1, sc.L2, sc.M3, sc.OMEGA, sc.RHO
E0, H = sc.E, sc.H
AREA, INERTIA = H * H, H**4 / 12
T_END, DT_OUT = 0.1, 1e-4
# Published elastic initial values (Y0 of slider_crank.py): q, q'.
Q0 = sc.Y0[3:7].copy()
QD0 = sc.Y0[10:14].copy()


def initial_state(k=1.0):
    """Elastic initial values divided by k, with phi2', x3, x3' from the constraints."""
    q, qd = Q0 / k, QD0 / k
    phi2d = -L1 * OMEGA / (L2 + q[3])
    return q, qd, phi2d


class Beam:
    """The rod as n co-rotational beam elements; node 0 on the crank pin, node n on the slider."""

    def __init__(self, n_el, E=E0):
        self.n, self.l0 = n_el, L2 / n_el
        self.ea_l0, self.ei_l0 = E * AREA / self.l0, E * INERTIA / self.l0
        lump = np.full(n_el + 1, 1.0)
        lump[[0, -1]] = 0.5
        mass = np.vstack([RHO * AREA * self.l0 * lump, RHO * AREA * self.l0 * lump,
                          RHO * INERTIA * self.l0 * lump])
        mass[0, -1] += M3
        self.mass = mass
        self.free = np.ones_like(mass, dtype=bool)
        self.free[0:2, 0] = False   # crank pin: x, y prescribed
        self.free[1, -1] = False    # slider: y = 0
        self.minv = np.where(self.free, 1.0 / mass, 0.0)
        self.force = np.zeros_like(mass)

    def internal_force(self, p):
        """f_int (3, n+1) of the configuration p = (x, y, theta) (3, n+1)."""
        dx, dy = p[0, 1:] - p[0, :-1], p[1, 1:] - p[1, :-1]
        length = np.sqrt(dx * dx + dy * dy)
        c, s = dx / length, dy / length
        beta = np.arctan2(dy, dx)
        th1, th2 = p[2, :-1] - beta, p[2, 1:] - beta
        n_ax = self.ea_l0 * (length - self.l0)
        m1 = self.ei_l0 * (4 * th1 + 2 * th2)
        m2 = self.ei_l0 * (2 * th1 + 4 * th2)
        shear = (m1 + m2) / length
        fx, fy = c * n_ax + s * shear, s * n_ax - c * shear   # on node 2; minus that on node 1
        f = self.force
        f[:, :] = 0.0
        f[0, :-1] -= fx
        f[0, 1:] += fx
        f[1, :-1] -= fy
        f[1, 1:] += fy
        f[2, :-1] += m1
        f[2, 1:] += m2
        return f.copy()

    def initial(self, k=1.0):
        """Positions and velocities (3, n+1) from the published (or 1/k scaled) initial values."""
        q, qd, phi2d = initial_state(k)
        xm = np.linspace(0.0, L2, self.n + 1)
        s = xm / L2
        nm, ne = 4 * s * (1 - s), s * (2 * s - 1)
        u = q[2] * nm + q[3] * ne
        p = np.vstack([L1 + xm + u, 0 * xm, 0 * xm])
        w_dot = qd[0] * np.sin(np.pi * s) + qd[1] * np.sin(2 * np.pi * s)
        w_dot_x = np.pi / L2 * (qd[0] * np.cos(np.pi * s) + 2 * qd[1] * np.cos(2 * np.pi * s))
        v = np.vstack([qd[2] * nm + qd[3] * ne,
                       L1 * OMEGA + phi2d * (xm + u) + w_dot,
                       phi2d + w_dot_x])
        return p, v

    def frequencies(self, p):
        """Circular frequencies of the linearized free system at p (ascending)."""
        idx = np.flatnonzero(self.free.ravel())
        eps = 1e-9
        cols = []
        for j in idx:
            dp = np.zeros(p.size)
            dp[j] = eps
            dp = dp.reshape(p.shape)
            cols.append((self.internal_force(p + dp) - self.internal_force(p - dp)).ravel()[idx] / (2 * eps))
        k = np.array(cols).T
        k = 0.5 * (k + k.T)
        d = 1.0 / np.sqrt(self.mass.ravel()[idx])
        lam = np.linalg.eigvalsh(d[:, None] * k * d[None, :])
        return np.sqrt(np.abs(lam)) * np.sign(lam)

    def run(self, k=1.0, refine=1, safety=0.8):
        """Integrate to T_END (E and initial values as for the scale k, see initial_state).

        Returns a dict: t, q1 (mid-node distance from the chord), q1_sine (the half-sine
        coefficient of the lateral displacement from the chord, 2 int_0^1 w sin(pi s) ds, Simpson
        over the nodes: the published model's q1), x3, every DT_OUT; the step h and omega_max."""
        p, v = self.initial(k)
        omega_max = self.frequencies(p)[-1]
        n_sub = int(np.ceil(DT_OUT / (safety * 2.0 / omega_max))) * refine
        h = DT_OUT / n_sub
        v[1, -1] = 0.0          # consistent by construction (checked in main)
        n_out = int(round(T_END / DT_OUT))
        out = {"t": np.arange(n_out + 1) * DT_OUT, "h": h, "omega_max": omega_max}
        q1, q1_sine, x3 = np.zeros(n_out + 1), np.zeros(n_out + 1), np.zeros(n_out + 1)
        simpson = np.ones(self.n + 1)
        simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
        sine = 2.0 / (3 * self.n) * simpson * np.sin(np.pi * np.linspace(0, 1, self.n + 1))
        minv = self.minv
        vh = v - 0.5 * h * (self.internal_force(p) * minv)
        for j in range(n_out + 1):
            lateral = chord_deflection(p[:, 0], p[:, -1], p)
            q1[j], q1_sine[j], x3[j] = lateral[self.n // 2], sine @ lateral, p[0, -1]
            if j == n_out:
                break
            for i in range(n_sub):
                p += h * vh
                t = (j * n_sub + i + 1) * h
                p[0, 0], p[1, 0] = L1 * np.cos(OMEGA * t), L1 * np.sin(OMEGA * t)
                vh -= h * (self.internal_force(p) * minv)
        out.update(q1=q1, q1_sine=q1_sine, x3=x3)
        return out


def chord_deflection(a, b, m):
    """Signed distance of m (or of the columns of m) from the line a-b, positive along
    e_z x (b - a)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    return (dx * (m[1] - a[1]) - dy * (m[0] - a[0])) / np.hypot(dx, dy)


# --- The published (Galerkin, chord frame) model of slider_crank.py, with E scaled and with
# --- variants of its axial-lateral coupling.

GAUSS_S, GAUSS_W = np.polynomial.legendre.leggauss(32)
GAUSS_S, GAUSS_W = 0.5 * (GAUSS_S + 1), 0.5 * GAUSS_W
# d/ds of the lateral shapes sin(pi s), sin(2 pi s) and of the axial shapes N_m, N_e, s = x/L2.
D_LAT = np.vstack([np.pi * np.cos(np.pi * GAUSS_S), 2 * np.pi * np.cos(2 * np.pi * GAUSS_S)])
D_AX = np.vstack([4 - 8 * GAUSS_S, 4 * GAUSS_S - 1])
GRAM_AX = (D_AX * GAUSS_W) @ D_AX.T


def coupling_force(q, kind):
    """Gradient of the nonlinear part of the rod's membrane energy, by Gauss quadrature.

    kind "cubic":   U = EA/2 int u' w'^2 dx               (the test set's term, slider_crank.coupling)
    kind "vk":      U = EA/2 int (u' + w'^2/2)^2 dx - EA/2 int u'^2 dx   (complete von Karman)
    kind "assumed": as "vk" with w'^2/2 replaced by its L2 projection onto the strain space of the
                    axial shapes (linear in x): no spurious membrane strain (locking-free).
    """
    ea = E0 * AREA
    wx = (q[:2] @ D_LAT) / L2
    ux = (q[2:] @ D_AX) / L2
    g = 0.5 * wx**2
    if kind == "cubic":
        n_eff = ux
    elif kind == "vk":
        n_eff = ux + g
    elif kind == "assumed":
        n_eff = ux + np.linalg.solve(GRAM_AX, (D_AX * GAUSS_W) @ g) @ D_AX
    else:
        raise ValueError(kind)
    # int over x = L2 int over s; d(w')/dq_i = D_LAT_i / L2, d(u')/dq_j = D_AX_j / L2.
    lateral = ea * (D_LAT * GAUSS_W) @ (n_eff * wx)
    axial = ea * (D_AX * GAUSS_W) @ g
    return np.concatenate([lateral, axial])


def galerkin(k=1.0, coupling=None, axial_mass=1.0, rtol=1e-10):
    """slider_crank.py's model with E scaled by k (elastic initial values / k), optionally with a
    nonlinear coupling: a kind of coupling_force, or "test set" (slider_crank.coupling), and with
    its axial mass block scaled by axial_mass. Returns a dict: t, q1, x3 every DT_OUT."""
    q, qd, phi2d = initial_state(k)
    y0 = np.concatenate([[0.0, 0.0, L1 + L2 + q[3]], q, [OMEGA, phi2d, qd[3]], qd])
    saved = sc.KQ, sc.MQ, sc.coupling
    sc.KQ = sc.KQ * k
    sc.MQ = sc.MQ.copy()
    sc.MQ[2:, 2:] *= axial_mass
    if coupling not in (None, "test set"):
        sc.coupling = lambda qq: coupling_force(qq, coupling)
    nonlinear = coupling is not None
    try:
        t = np.arange(int(round(T_END / DT_OUT)) + 1) * DT_OUT
        sol = solve_ivp(lambda tt, y: np.concatenate([y[7:], sc.accelerations(y[:7], y[7:], nonlinear)]),
                        (0, T_END), y0, method="DOP853", rtol=rtol, atol=1e-14, t_eval=t)
        assert sol.success, sol.message
    finally:
        sc.KQ, sc.MQ, sc.coupling = saved
    return {"t": t, "q1": sol.y[3], "x3": sol.y[2]}


def rel_max(a, b):
    """max |a - b| / max |b|."""
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def amplitude(x):
    return np.max(np.abs(x))


def job(spec):
    """Run one model: ("beam", n_el, k, refine) or ("galerkin", k, coupling, axial_mass)."""
    t0 = time.time()
    if spec[0] == "beam":
        _, n_el, k, refine = spec
        out = Beam(n_el, E0 * k).run(k, refine)
    else:
        _, k, coupling, axial_mass = spec
        out = galerkin(k, coupling, axial_mass)
    out["wall"] = time.time() - t0
    return spec, out


BEAM_FINE = ("beam", 64, 1, 1)
BEAM_SCALE_MESH = 32


def job_list(quick):
    if quick:
        return [("beam", BEAM_SCALE_MESH, 1, 1), ("galerkin", 1, None, 1.0), ("galerkin", 1, "assumed", 1.0)]
    # longest first (two workers)
    return [("galerkin", 100, None, 1.0), ("beam", BEAM_SCALE_MESH, 100, 1), ("galerkin", 10, None, 1.0),
            ("beam", 64, 1, 2), ("beam", BEAM_SCALE_MESH, 10, 1), ("galerkin", 1, "assumed", 1.0),
            ("galerkin", 1, "assumed", 1 / 15), ("galerkin", 1, "vk", 1.0),
            ("galerkin", 1, "test set", 1.0), BEAM_FINE, ("galerkin", 1, None, 1.0),
            ("beam", 32, 1, 1), ("beam", 16, 1, 1)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--histories", default="/tmp/sc/histories.json",
                    help="flexopt's q1 histories (JSON: t, acf_8mm, ffrf_4modes); skipped if missing")
    ap.add_argument("--quick", action="store_true", help="32-element beam and Galerkin k = 1 only")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes")
    a = ap.parse_args()
    t_start = time.time()

    q, qd, phi2d = initial_state()
    print(f"initial values: phi2' from the constraint {phi2d:.9f} (published {sc.Y0[8]:.9f}); slider y "
          f"velocity with the published phi2' {L1 * OMEGA + sc.Y0[8] * (L2 + q[3]):.1e} m/s")
    beam = Beam(64)
    p0, _ = beam.initial()
    straight = p0.copy()
    straight[0] = L1 + np.linspace(0, L2, beam.n + 1)
    w_euler = np.pi**2 * np.sqrt(E0 * INERTIA / (RHO * AREA)) / L2**2
    print(f"first bending frequency, 64 elements: unstressed {beam.frequencies(straight)[0]:.1f} rad/s "
          f"(Euler-Bernoulli pinned {w_euler:.1f}); at t = 0 {beam.frequencies(p0)[0]:.1f} (the published "
          f"start is stretched by q4: N = {E0 * AREA * q[3] / L2:.0f} N, Euler load "
          f"{np.pi**2 * E0 * INERTIA / L2**2:.0f} N)")

    specs = job_list(a.quick)
    if a.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(a.jobs) as pool:
            res = dict(pool.map(job, specs))
    else:
        res = dict(map(job, specs))
    for spec, out in res.items():
        extra = (f", step {out['h']:.3e} s (omega_max {out['omega_max']:.3e} rad/s)"
                 if spec[0] == "beam" else "")
        print(f"  run {spec}: {out['wall']:.1f} s{extra}")

    ref_spec = ("beam", BEAM_SCALE_MESH, 1, 1) if a.quick else BEAM_FINE
    ref = res[ref_spec]
    lin = res[("galerkin", 1, None, 1.0)]
    print(f"\nreference: beam {ref_spec[1]} elements; published t = 0.1 s: "
          f"x3 = {sc.PUBLISHED['x3']:.10f}, q1 = {sc.PUBLISHED['q1']:.6e}")
    print("1. convergence of the beam (q1 = mid-node deflection from the chord, k = 1):")
    print("   elements  refine  step [s]   amplitude    q1(0.1)       x3(0.1)       "
          "max|q1 - q1_ref|/max|q1_ref|")
    for spec in sorted(s for s in res if s[0] == "beam" and s[2] == 1):
        out = res[spec]
        print(f"   {spec[1]:8d}  {spec[3]:6d}  {out['h']:.3e}  {amplitude(out['q1']):.5e}  "
              f"{out['q1'][-1]:.5e}  {out['x3'][-1]:.10f}  {rel_max(out['q1'], ref['q1']):.2e}")

    print("2. linear limit: beam vs the linear Galerkin model (slider_crank.py), E and initial elastic "
          "values scaled by k, 1/k:")
    print("   k     beam amplitude  linear amplitude  max|diff|/max|lin|: mid-node q1   half-sine q1")
    for k in ((1,) if a.quick else (1, 10, 100)):
        b_out = res[("beam", BEAM_SCALE_MESH, k, 1)]
        g_out = lin if k == 1 else res[("galerkin", k, None, 1.0)]
        print(f"   {k:<4d}  {amplitude(b_out['q1']):.5e}     {amplitude(g_out['q1']):.5e}       "
              f"{100 * rel_max(b_out['q1'], g_out['q1']):8.3f} %              "
              f"{100 * rel_max(b_out['q1_sine'], g_out['q1']):8.3f} %")
    print(f"   (beam {BEAM_SCALE_MESH} elements; linear Galerkin at k = 1: q1(0.1) = {lin['q1'][-1]:.10e}, "
          f"x3(0.1) = {lin['x3'][-1]:.10f})")

    if os.path.exists(a.histories):
        import json
        with open(a.histories) as f:
            hist = json.load(f)
        assert np.allclose(hist["t"], ref["t"]), "histories not sampled every 1e-4 s from 0 to 0.1 s"
        print(f"3. flexopt ({a.histories}) against the beam:")
        print("   model          amplitude    q1(0.1)       max|q1 - q1_beam|/max|q1_beam|")
        print(f"   beam           {amplitude(ref['q1']):.5e}  {ref['q1'][-1]:.5e}")
        for key in ("acf_8mm", "ffrf_4modes"):
            x = np.asarray(hist[key])
            print(f"   {key:13s}  {amplitude(x):.5e}  {x[-1]:.5e}  {100 * rel_max(x, ref['q1']):.2f} %")
    else:
        print(f"3. skipped: no {a.histories}")

    print("4. Galerkin model variants against the beam (mid-point q1):")
    print("   variant                               amplitude    q1(0.1)       x3(0.1)       "
          "max|q1 - q1_beam|/max|q1_beam|")
    labels = {(None, 1.0): "linear (published)", ("test set", 1.0): "test set coupling (cubic energy)",
              ("vk", 1.0): "complete von Karman", ("assumed", 1.0): "von Karman, assumed membrane strain",
              ("assumed", 1 / 15): "  same, consistent axial mass"}
    for (coupling, axial_mass), label in labels.items():
        spec = ("galerkin", 1, coupling, axial_mass)
        if spec in res:
            out = res[spec]
            print(f"   {label:36s}  {amplitude(out['q1']):.5e}  {out['q1'][-1]:.5e}  {out['x3'][-1]:.10f}  "
                  f"{100 * rel_max(out['q1'], ref['q1']):6.2f} %")
    short = (np.pi * ref["q1_sine"][-1] / L2)**2 * L2 / 4 * np.cos(sc.PUBLISHED["phi2"])
    print(f"x3(0.1): beam - linear = {ref['x3'][-1] - lin['x3'][-1]:.2e} m; the bow's shortening of the "
          f"chord (pi q1/L2)^2 L2/4 cos(phi2) = {short:.2e} m (left out by the linear model)")
    print(f"run time {time.time() - t_start:.0f} s")


if __name__ == "__main__":
    main()
