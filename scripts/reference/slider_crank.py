#!/usr/bin/env python3
"""Reference model of Simeon's flexible slider-crank (cases/slider_crank_flexible).

Model (Simeon 1996, Math. Modelling of Systems 2; the "crank" problem of the IVP test set, as
defined there). Planar; coordinates p = (phi1, phi2, x3, q1, q2, q3, q4): crank angle, angle of
the chord of the rod (crank pin to wrist pin), slider position, and the rod's elastic
coordinates in the chord frame: lateral w(x) = q1 sin(pi x/L) + q2 sin(2 pi x/L), axial
u(x) = q3 N_m(x) + q4 N_e(x) with the quadratic shape functions N_m = 4 s (1 - s),
N_e = s (2 s - 1), s = x/L (so q4 is the axial displacement of the wrist pin). Crank rigid and
driven, phi1 = 150 t; slider a point mass m3 on the x axis; no gravity, no damping.

The equations, M(p) p'' = f(p, p') - G^T lambda, G p'' = gamma, with
  mass:   M11 = J1 + m2 L1^2,  M12 = m2 L1 L2 cos(phi12)/2 + rho L1 (sin(phi12) c2.q + cos(phi12) c1.q),
          M22 = J2 + q.Mq q + 2 rho c12.q,  M33 = m3,
          M1,q = rho L1 (-sin(phi12) c1 + cos(phi12) c2),  M2,q = rho (c21 + q^T B),  Mqq = Mq,
  forces: f1 = -m2 L1 L2 w2^2 sin(phi12)/2 + rho L1 w2^2 (-sin(phi12) c1.q + cos(phi12) c2.q)
               - 2 rho L1 w2 (cos(phi12) c1.q' + sin(phi12) c2.q'),
          f2 = m2 L1 L2 w1^2 sin(phi12)/2 + rho L1 w1^2 (sin(phi12) c1.q - cos(phi12) c2.q)
               - 2 rho w2 c12.q' - 2 w2 q'.Mq q - rho q'^T B q',
          fq = w2^2 Mq q + rho (w2^2 c12 + L1 w1^2 (cos(phi12) c1 + sin(phi12) c2) + 2 w2 B q')
               - Kq q   [- the optional axial-lateral coupling fN(q), below],
  with phi12 = phi1 - phi2, w1 = phi1', w2 = phi2', and the constraints
          L1 sin(phi1) + (L2 + q4) sin(phi2) = 0,  x3 - L1 cos(phi1) - (L2 + q4) cos(phi2) = 0,
          phi1 - 150 t = 0.
The matrices are the test set's (Mq includes its factor rho A L on the axial block as written
there, 15 times the consistent axial mass; measured below: it changes q1(0.1) by 6e-5
relative). Integrated in index-1 form (accelerations and multipliers from the saddle-point
system) by scipy's DOP853 with rtol 1e-12.

Optional (the test set's "nonlinear stiffness term"): the axial-lateral coupling fN(q),
quadratic in q, the gradient of the cubic membrane energy EA/2 int u' w'^2 only. It is not the
P-delta effect of a geometrically nonlinear rod: without the quartic EA/8 int w'^4 its lateral
force carries a false compression EA (pi q1 / L)^2 / 4 that softens the rod (measured against
the geometrically exact beam of slider_crank_beam.py, which gives the P-delta effect: -5.5 % of
the amplitude where this term gives +40 %).

What it prints:
  1. the published values at t = 0.1 s reproduced from the published initial values;
  2. q1(0.1) from the undeformed start that flexopt used before (the rod straight and at rest
     in the chord frame): the published value depends entirely on the initial elastic state;
  3. the periodic amplitude of q1 (free vibration damped out by stiffness-proportional damping
     C = 7.8e-5 K on the lateral coordinates, 5 % at the first pinned frequency), linear and
     with the axial-lateral coupling: how much the coupling moves the deflection.

Usage: scripts/reference/slider_crank.py
"""
import numpy as np
from scipy.integrate import solve_ivp

L1, L2 = 0.15, 0.30
M2, M3 = 0.151104, 0.075552
J1, J2 = 0.002727, 0.0045339259
E, B, H, RHO = 2.0e11, 0.008, 0.008, 7870.0
OMEGA = 150.0

FM, FK, FB = RHO * B * H * L2, E * B * H / L2, B * H * L2
MQ = np.zeros((4, 4))
MQ[0, 0] = MQ[1, 1] = FM / 2
MQ[2:, 2:] = FM * np.array([[8.0, 1.0], [1.0, 2.0]])
KQ = np.zeros((4, 4))
KQ[0, 0] = FK * np.pi**4 / 24 * (H / L2)**2
KQ[1, 1] = FK * np.pi**4 * 2 / 3 * (H / L2)**2
KQ[2:, 2:] = FK / 3 * np.array([[16.0, -8.0], [-8.0, 7.0]])
BQ = np.zeros((4, 4))  # skew: the Coriolis coupling of lateral and axial shapes
BQ[0, 2] = -FB * 16 / np.pi**3
BQ[0, 3] = FB * (8 / np.pi**3 - 1 / np.pi)
BQ[1, 3] = FB * 0.5 / np.pi
BQ -= BQ.T
C1 = np.array([0, 0, FB * 2 / 3, FB / 6])               # int N_axial dx / L2 * FB
C2 = np.array([FB * 2 / np.pi, 0, 0, 0])                # int N_lateral
C12 = L2 * np.array([0, 0, FB / 3, FB / 6])             # int x N_axial
C21 = L2 * np.array([FB / np.pi, -FB * 0.5 / np.pi, 0, 0])  # int x N_lateral

# Published initial values (crank.f, "close to smooth motion") and values at t = 0.1 s.
Y0 = np.array([0, 0, 0.450016933, 0, 0, 0.103339863e-4, 0.169327969e-4,
               150.0, -74.9957670, -0.268938672e-5, 0.444896105, 0.463434311e-2,
               -0.178591076e-5, -0.268938672e-5])
PUBLISHED = {"phi2": -0.3311734987910881, "x3": 0.1697373326718410,
             "q1": 1.893192460247178e-4, "q2": 2.375751865617931e-5}


def coupling(q):
    """The test set's axial-lateral coupling force of the nonlinear rod (subtracted from fq)."""
    fk, fb = 0.5 * E * B * H / L2**2 * np.pi**2, 80 / (np.pi**2 * 9)
    s = -4 * q[2] + 2 * q[3]
    return fk * np.array([q[0] * q[3] - fb * q[1] * s,
                          4 * q[1] * q[3] - fb * q[0] * s,
                          4 * fb * q[0] * q[1],
                          0.5 * q[0]**2 + 2 * q[1]**2 - 2 * fb * q[0] * q[1]])


def accelerations(p, v, nonlinear=False, damping=0.0):
    phi1, phi2 = p[0], p[1]
    q, qd = p[3:], v[3:]
    w1, w2 = v[0], v[1]
    s12, c12 = np.sin(phi1 - phi2), np.cos(phi1 - phi2)
    M = np.zeros((7, 7))
    M[0, 0] = J1 + M2 * L1**2
    M[0, 1] = 0.5 * L1 * L2 * M2 * c12 + RHO * L1 * (s12 * (C2 @ q) + c12 * (C1 @ q))
    M[1, 1] = J2 + q @ MQ @ q + 2 * RHO * (C12 @ q)
    M[2, 2] = M3
    M[0, 3:] = RHO * L1 * (-s12 * C1 + c12 * C2)
    M[1, 3:] = RHO * (C21 + q @ BQ)
    M[3:, 3:] = MQ
    M = np.triu(M) + np.triu(M, 1).T
    f = np.zeros(7)
    f[0] = (-0.5 * L1 * L2 * M2 * w2**2 * s12 + RHO * L1 * w2**2 * (-s12 * (C1 @ q) + c12 * (C2 @ q))
            - 2 * RHO * L1 * w2 * (c12 * (C1 @ qd) + s12 * (C2 @ qd)))
    f[1] = (0.5 * L1 * L2 * M2 * w1**2 * s12 + RHO * L1 * w1**2 * (s12 * (C1 @ q) - c12 * (C2 @ q))
            - 2 * RHO * w2 * (C12 @ qd) - 2 * w2 * (qd @ MQ @ q) - RHO * (qd @ BQ @ qd))
    f[3:] = (w2**2 * (MQ @ q) + RHO * (w2**2 * C12 + L1 * w1**2 * (c12 * C1 + s12 * C2) + 2 * w2 * (BQ @ qd))
             - KQ @ q)
    if nonlinear:
        f[3:] -= coupling(q)
    if damping:
        f[3:5] -= damping * (KQ[:2, :2] @ qd[:2])
    ell, ell_d = L2 + q[3], qd[3]
    G = np.zeros((3, 7))
    G[0, [0, 1, 6]] = L1 * np.cos(phi1), ell * np.cos(phi2), np.sin(phi2)
    G[1, [0, 1, 2, 6]] = L1 * np.sin(phi1), ell * np.sin(phi2), 1.0, -np.cos(phi2)
    G[2, 0] = 1.0
    # G p'' = gamma = -(d/dt G) p'
    gamma = -np.array([-L1 * np.sin(phi1) * w1**2 - ell * np.sin(phi2) * w2**2 + 2 * w2 * np.cos(phi2) * ell_d,
                       L1 * np.cos(phi1) * w1**2 + ell * np.cos(phi2) * w2**2 + 2 * w2 * np.sin(phi2) * ell_d,
                       0.0])
    A = np.block([[M, G.T], [G, np.zeros((3, 3))]])
    return np.linalg.solve(A, np.concatenate([f, gamma]))[:7]


def integrate(y0, t_eval, **model):
    rhs = lambda t, y: np.concatenate([y[7:], accelerations(y[:7], y[7:], **model)])
    sol = solve_ivp(rhs, (0, t_eval[-1]), y0, method="DOP853", rtol=1e-12, atol=1e-14, t_eval=t_eval)
    assert sol.success, sol.message
    return sol.y


def peaks(t, x, floor=5e-4):
    """Interior extrema of |x| above `floor`: (t, x) pairs."""
    return [(t[k], x[k]) for k in range(1, len(x) - 1)
            if abs(x[k]) > abs(x[k - 1]) and abs(x[k]) >= abs(x[k + 1]) and abs(x[k]) > floor]


def main():
    t = np.linspace(0, 0.1, 10001)
    y = integrate(Y0, t)
    print("1. published initial values, t = 0.1 s (computed vs published):")
    for k, name in ((1, "phi2"), (2, "x3"), (3, "q1"), (4, "q2")):
        print(f"   {name:5s} {y[k, -1]: .10e}  {PUBLISHED[name]: .10e}  rel diff {abs(y[k, -1] / PUBLISHED[name] - 1):.1e}")
    global MQ
    saved = MQ.copy()
    MQ[2:, 2:] /= 15
    q1_mass = integrate(Y0, t[[0, -1]])[3, -1]
    MQ = saved
    print(f"   with the consistent axial mass (1/15 of the test set's): q1(0.1) = {q1_mass:.6e}")
    rest = np.zeros(14)
    rest[2], rest[7], rest[8] = L1 + L2, OMEGA, -OMEGA * L1 / L2
    print(f"2. undeformed start (rod straight and at rest in the chord frame): "
          f"q1(0.1) = {integrate(rest, t[[0, -1]])[3, -1]:.6e}")
    print("3. periodic amplitude of q1 (lateral damping 7.8e-5 K, published start), extrema |q1| > 5e-4 m:")
    for label, nonlinear in (("linear (the reference)", False), ("with the axial-lateral coupling", True)):
        q1 = integrate(Y0, t, nonlinear=nonlinear, damping=7.8e-5)[3]
        late = [x for (tk, x) in peaks(t, q1) if tk > 0.03]
        print(f"   {label:32s} " + " ".join(f"{x:+.4e}" for x in late) +
              f"   mean |extremum| {np.mean(np.abs(late)):.4e}")


if __name__ == "__main__":
    main()
