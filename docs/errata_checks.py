#!/usr/bin/env python3
"""Independent numerical checks of Painter, Kerstetter & Jowers (1990),
"Reconciling Steady-State Kalman and Alpha-Beta Filter Design", IEEE T-AES.

Companion of docs/errata.md.  Standalone: numpy, scipy, mpmath only; < 30 s.

Every printed equation (1)-(17) and every worked number of the GPS example is
checked against something computed independently of the printed formula:
scipy.linalg.solve_discrete_are, brute-force Riccati iteration in mpmath
(50 digits), mpmath polynomial roots, scipy.integrate.quad, solve_ivp and
Monte-Carlo simulation.

Each line prints PASS or FAIL for one item.  A FAIL on a line tagged
"[printed]" is the documented erratum (the printed form is wrong); the line
tagged "[corrected]" that follows must PASS.  The script exits 0 iff every
verdict equals the one recorded in docs/errata.md.
"""
import sys
import time

import mpmath as mp
import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.linalg import expm, solve_discrete_are
from scipy.optimize import brentq, minimize_scalar
from scipy.signal import ss2tf

T0 = time.time()
mp.mp.dps = 50
RNG = np.random.default_rng(19901101)
SQ2 = np.sqrt(2.0)

_results = []


def check(item, desc, ok, detail="", *, expect=True):
    """Record one verdict. expect=False marks a printed form known to be wrong."""
    ok = bool(ok)
    verdict = "PASS" if ok else "FAIL"
    tag = "" if expect else "  (expected FAIL: erratum)"
    print(f"{verdict}  [{item}] {desc}{tag}")
    if detail:
        print(f"        {detail}")
    _results.append(ok == expect)


def rel(a, b):
    return abs(a - b) / abs(b)


# ----------------------------------------------------------------------------
# Independent reference solutions
# ----------------------------------------------------------------------------
FN = np.array([[1.0, 1.0], [0.0, 1.0]])
HN = np.array([[1.0], [0.0]])
QSHAPE = np.array([[1.0, 2.0], [2.0, 4.0]])


def dare_filtered(F, h, Q, R):
    """Filtered (a-posteriori) steady-state covariance via scipy DARE."""
    M = solve_discrete_are(F.T, h, Q, np.array([[R]]))  # predicted covariance
    S = (h.T @ M @ h)[0, 0] + R
    return M - (M @ h @ h.T @ M) / S, M


def ref_PN(r):
    P, _ = dare_filtered(FN, HN, r * QSHAPE, 1.0)
    return P


def mp_riccati(r, iters=20000, tol=mp.mpf("1e-40")):
    """Brute-force Riccati recursion (predict/update) in 50-digit arithmetic."""
    r = mp.mpf(r)
    F = mp.matrix([[1, 1], [0, 1]])
    Q = r * mp.matrix([[1, 2], [2, 4]])
    P = mp.matrix([[1, 0], [0, 1]])
    for _ in range(iters):
        M = F * P * F.T + Q
        k = M[:, 0] / (M[0, 0] + 1)
        Pn = M - k * M[0, :]
        if mp.norm(Pn - P) < tol:
            return Pn
        P = Pn
    return P


# ----------------------------------------------------------------------------
# Printed formulas (as transcribed) and corrected forms
# ----------------------------------------------------------------------------
def p11_printed(r):  # eq (12)/(14), both transcriptions agree
    a = r + 4 * np.sqrt(r)
    return (a / 2) * (np.sqrt(1 + 4 / a) - 1)


def p12_000(p11, r):  # transcription 000: (p11^2 + r(1-p11))/2 - p11
    return (p11**2 + r * (1 - p11)) / 2 - p11


def p12_003(p11, r):  # transcription 003: (p11^2 + r(1-p11))/(2 - p11)
    return (p11**2 + r * (1 - p11)) / (2 - p11)


def p22_printed(p11, p12, r):  # eq (12)
    return p11 * p12 / (1 - p11) - 2 * r


def gains_stable(r):
    """Cancellation-free evaluation of (12) (recommended for code)."""
    a = r + 4 * np.sqrt(r)
    s = np.sqrt(1 + 4 / a)
    p11 = 2 / (1 + s)
    one_m = 4 / (a * (1 + s) ** 2)  # 1 - p11
    p12 = (p11**2 + r * one_m) / (2 - p11)
    p22 = p12 * (2 * p11 - p12) / (2 * one_m)
    return p11, p12, p22


def bnt_printed(beta, delta):  # eq (16)
    sb = np.sqrt(beta)
    return sb / (8 * delta) * (1 + (2 * delta - sb) ** 2)


R_GRID = np.logspace(-9, 3, 49)

print("Painter, Kerstetter & Jowers (1990) -- numerical errata checks")
print("=" * 72)

# ----------------------------------------------------------------------------
# (1)-(2): ZOH discretisation of the double integrator
# ----------------------------------------------------------------------------
A = np.array([[0.0, 1.0], [0.0, 0.0]])
b = np.array([[0.0], [1.0]])
for T in (0.1, 0.37, 2.0):
    aug = np.zeros((3, 3))
    aug[:2, :2] = A
    aug[:2, 2:] = b
    E = expm(aug * T)
    F_ok = np.allclose(E[:2, :2], [[1, T], [0, 1]], rtol=0, atol=1e-13)
    d_ok = np.allclose(E[:2, 2], [T**2 / 2, T], rtol=0, atol=1e-13)
    check("eq2", f"F=exp(AT)=[[1,T],[0,1]], d=[T^2/2,T] (expm of augmented matrix, T={T})",
          F_ok and d_ok)

# ----------------------------------------------------------------------------
# (4), (3), (5): information-form Riccati = filtered covariance, g = P h/sv^2
# ----------------------------------------------------------------------------
sw, sv, T = 3.2, 32.0, 0.1
F = np.array([[1.0, T], [0.0, 1.0]])
d = np.array([[T**2 / 2], [T]])
h = np.array([[1.0], [0.0]])
P, M = dare_filtered(F, h, d @ d.T * sw**2, sv**2)
lhs = np.linalg.inv(P)
rhs = np.linalg.inv(F @ P @ F.T + d @ d.T * sw**2) + h @ h.T / sv**2
check("eq4", "P^-1 = [F P F' + d d' sw^2]^-1 + h h'/sv^2 holds for DARE filtered P (GPS model)",
      np.allclose(lhs, rhs, rtol=1e-9, atol=0),
      f"max rel residual = {np.max(np.abs(lhs - rhs) / np.abs(rhs).max()):.3e}")
g = P @ h / sv**2
Kstd = M @ h / ((h.T @ M @ h)[0, 0] + sv**2)
check("eq4", "g = P h/sv^2 equals the standard Kalman gain M h/(h'Mh+sv^2)",
      np.allclose(g, Kstd, rtol=1e-10, atol=0),
      f"g = [{g[0,0]:.9g}, {g[1,0]:.9g}]")
# eq (3)/(5): fixed-gain filter is the alpha-beta filter with g1=alpha, g2=beta/T
al, be = 0.5, 0.2
x = np.array([1.3, -0.4])
z = 2.1
gv = np.array([al, be / T])
xk = F @ x + gv * (z - (F @ x)[0])
xp = x[0] + T * x[1]
xab = np.array([xp + al * (z - xp), x[1] + be / T * (z - xp)])
check("eq3/5", "x(k)=F x(k-1)+g e(k), e=z-h'F x(k-1) with g=[alpha,beta/T] is the alpha-beta update",
      np.allclose(xk, xab, rtol=0, atol=1e-14))

# ----------------------------------------------------------------------------
# (6), (7), Fig. 3 reconstruction
# Reconstruction: xh1' = xh2 + b1 e, xh2' = b2 e, e = z - xh1 - T xh2
# (feedback gain T from xh2, as the text says); for the discretisation e is
# sampled and held (ZOH) as in the generator of Fig. 1.
# ----------------------------------------------------------------------------
for (delta, wn, T) in [(1 / SQ2, 6.0, 0.1), (0.4, 2.0, 0.3), (1.3, 0.7, 1.0)]:
    b1 = wn * (2 * delta - wn * T)
    b2 = wn**2
    # (6): g = int_0^T exp(Aq)[b1,b2] dq
    aug = np.zeros((3, 3))
    aug[:2, :2] = A
    aug[:2, 2] = [b1, b2]
    gz = expm(aug * T)[:2, 2]
    g6 = np.array([b1 * T + b2 * T**2 / 2, b2 * T])
    check("eq6", f"g1=b1T+b2T^2/2, g2=b2T (ZOH integral, delta={delta:.4g}, wn={wn}, T={T})",
          np.allclose(gz, g6, rtol=1e-12, atol=0))
    # algebra (7) -> alpha, beta
    alpha = (wn * T) * (2 * delta - wn * T / 2)
    beta = (wn * T) ** 2
    check("eq7", "alpha=(wnT)(2delta-wnT/2), beta=(wnT)^2 from (6)+(7); and (15) alpha=2delta sqrt(beta)-beta/2",
          abs(g6[0] - alpha) < 1e-13 and abs(g6[1] * T - beta) < 1e-13
          and abs(alpha - (2 * delta * np.sqrt(beta) - beta / 2)) < 1e-13)
    # Fig. 3 transfer function
    Ac = np.array([[-b1, 1 - b1 * T], [-b2, -b2 * T]])
    Bc = np.array([[b1], [b2]])
    Cc = np.array([[1.0, 0.0]])
    num, den = ss2tf(Ac, Bc, Cc, np.zeros((1, 1)))
    K = wn * (2 * delta - wn * T)
    zz = -wn / (2 * delta - wn * T)
    ok = (np.allclose(den, [1, 2 * delta * wn, wn**2], rtol=1e-12, atol=1e-12)
          and np.allclose(num[0][-2:], [K, -K * zz], rtol=1e-12, atol=1e-12))
    check("eq7-TF", "reconstructed Fig.3 gives Y/Z = K(s-z)/(s^2+2 delta wn s+wn^2), K=wn(2delta-wnT), z=-wn/(2delta-wnT)", ok)

# Hybrid simulation of Fig. 3 (ODE solver, e held over each interval) versus
# the discrete recursion (3) with g from (6): xd(k) == xc((k+1)T).
delta, wn, T = 1 / SQ2, 6.0, 0.1
b1, b2 = wn * (2 * delta - wn * T), wn**2
gd = np.array([b1 * T + b2 * T**2 / 2, b2 * T])
Fd = np.array([[1, T], [0, 1.0]])
zs = np.cumsum(RNG.normal(size=60)) + 0.3 * np.arange(60)
xc = np.zeros(2)
xd = np.zeros(2)
errmax = 0.0
for k in range(60):
    e = zs[k] - xc[0] - T * xc[1]
    sol = solve_ivp(lambda t, y: [y[1] + b1 * e, b2 * e], (0, T), xc, rtol=1e-12, atol=1e-12,
                    method="DOP853")
    xc = sol.y[:, -1]
    xd = Fd @ xd + gd * (zs[k] - (Fd @ xd)[0])
    errmax = max(errmax, np.max(np.abs(xc - xd)))
check("eq6-sim", "ODE simulation of Fig.3 with sampled/held e reproduces recursion (3) exactly",
      errmax < 1e-8, f"max |xc((k+1)T) - xd(k)| over 60 steps = {errmax:.2e}")

# Closed-loop poles: discrete filter vs exp(sT) (informational: (6) is a
# ZOH discretisation of the open-loop integrators, not impulse invariance of
# the closed-loop transfer function)
alpha, beta = (wn * T) * (2 * delta - wn * T / 2), (wn * T) ** 2
zd = np.sort_complex(np.roots([1, -(2 - alpha - beta), 1 - alpha]))
sc = np.roots([1, 2 * delta * wn, wn**2])
ze = np.sort_complex(np.exp(sc * T))
print(f"INFO  [eq6] closed-loop poles (delta=1/sqrt2, wnT=0.6): discrete {np.round(zd, 6)}, "
      f"exp(sT) {np.round(ze, 6)}")

# Type-1 remark: continuous TF leaves ramp error v*T, discrete filter leaves 0
Hc0_ramp = (b2 * T) / wn**2  # lim_{s->0} (1-H(s))/s = (2 delta wn - b1)/wn^2
xd = np.zeros(2)
v = 1.0
for k in range(400):
    xd = Fd @ xd + gd * (v * k * T - (Fd @ xd)[0])
ramp_err_d = v * 399 * T - xd[0]
check("type", "continuous Y/Z is Type-1 (ramp lag = v*T); discrete filter (3) is Type-2 (ramp error 0)",
      abs(Hc0_ramp - T) < 1e-14 and abs(ramp_err_d) < 1e-9,
      f"continuous ramp error/v = {Hc0_ramp:.6g} s (=T), discrete ramp error = {ramp_err_d:.2e}")

# ----------------------------------------------------------------------------
# (8) + appendix (17): normalisation
# ----------------------------------------------------------------------------
for T in (0.1, 0.5, 2.0):
    N = np.diag([1.0, 1 / T])
    Ninv = np.linalg.inv(N)
    d = np.array([[T**2 / 2], [T]])
    F = np.array([[1.0, T], [0.0, 1.0]])
    r = ((sw * T**2 / 2) / sv) ** 2
    check("eq17", f"F_N = N^-1 F N = [[1,1],[0,1]] (T={T})", np.allclose(Ninv @ F @ N, FN))
    dN17 = Ninv @ d / sv
    check("eq17", f"d_N = N^-1 d / sv = (1/sv)[T^2/2, T^2] (000) (T={T})",
          np.allclose(dN17.ravel(), np.array([T**2 / 2, T**2]) / sv, rtol=1e-14))
    check("eq17", f"d_N d_N' sw^2 = q q' = r[[1,2],[2,4]] with r of (9) (T={T})",
          np.allclose(dN17 @ dN17.T * sw**2, r * QSHAPE, rtol=1e-12))
    dN8 = np.array([[T / 2], [T]])  # as printed in the block under (8)
    check("eq8", f"[printed] d_N=[T/2,T] with factor sw^2/sv^2 gives r[[1,2],[2,4]] (T={T})",
          np.allclose(dN8 @ dN8.T * sw**2 / sv**2, r * QSHAPE, rtol=1e-6), expect=False,
          detail=f"printed gives {(dN8 @ dN8.T * sw**2 / sv**2)[0,0]:.6g}*[[1,2],[2,4]], "
          f"needed r = {r:.6g} (off by 1/T^2 = {1/T**2:g})")
    dN8c = np.array([[T**2 / 2], [T**2]])
    check("eq8", f"[corrected] d_N=[T^2/2,T^2] with factor sw^2/sv^2 gives r[[1,2],[2,4]] (T={T})",
          np.allclose(dN8c @ dN8c.T * sw**2 / sv**2, r * QSHAPE, rtol=1e-12))
    # raw-unit DARE vs normalised solution: P = sv^2 N P_N N, g = N P_N h
    Praw, _ = dare_filtered(F, h, d @ d.T * sw**2, sv**2)
    PN = ref_PN(r)
    check("eq8", f"P = sv^2 N P_N N and (8) [P_N^-1 - h h']^-1 = F_N P_N F_N' + r Q (T={T})",
          np.allclose(Praw, sv**2 * N @ PN @ N, rtol=1e-7, atol=0)
          and np.allclose(np.linalg.inv(np.linalg.inv(PN) - HN @ HN.T),
                          FN @ PN @ FN.T + r * QSHAPE, rtol=1e-7, atol=0))
    graw = Praw @ h / sv**2
    check("eq8/13", f"g = N P_N h (h=[1,0]) i.e. g1=p11, g2=p12/T (T={T})",
          np.allclose(graw, N @ PN @ HN, rtol=1e-7))

# Normalised filter of the appendix: x = sv N x_N, y = h_N' x_N, h_N = sv[1,0]
T = 0.1
N = np.diag([1.0, 1 / T])
Ninv = np.linalg.inv(N)
r = ((sw * T**2 / 2) / sv) ** 2
PN = ref_PN(r)
g = N @ PN @ HN
hN = sv * np.array([1.0, 0.0])
F = np.array([[1.0, T], [0.0, 1.0]])
x = np.zeros(2)
xn_a = np.zeros(2)  # g_N = N^-1 g / sv (consistent)
xn_b = np.zeros(2)  # g_N = N^-1 g      (as printed)
zs = RNG.normal(size=50) * sv
ea = eb = 0.0
for zk in zs:
    x = F @ x + g.ravel() * (zk - (F @ x)[0])
    xn_a = FN @ xn_a + (Ninv @ g).ravel() / sv * (zk - hN @ FN @ xn_a)
    xn_b = FN @ xn_b + (Ninv @ g).ravel() * (zk - hN @ FN @ xn_b)
    ea = max(ea, np.max(np.abs(sv * N @ xn_a - x)))
    eb = max(eb, np.max(np.abs(sv * N @ xn_b - x)))
check("eq17", "[printed] appendix filter with g_N = N^-1 g and h_N = sv[1,0] reproduces x = sv N x_N",
      eb < 1e-9, expect=False, detail=f"max deviation {eb:.3e} (effective gains too large by the factor sv)")
check("eq17", "[corrected] appendix filter with g_N = N^-1 g / sv and h_N = sv[1,0] reproduces x = sv N x_N",
      ea < 1e-9, f"max deviation {ea:.2e}")

# 003's reading of the appendix: x = N x_N (no sv), h_N = h' N = [1,0],
# g_N = N^-1 g, d_N = N^-1 d; covariance normalised by sv^2 separately.
x = np.zeros(2)
xn_c = np.zeros(2)
ec = 0.0
dN3 = Ninv @ np.array([T**2 / 2, T])
for zk in zs:
    x = F @ x + g.ravel() * (zk - (F @ x)[0])
    xn_c = FN @ xn_c + (Ninv @ g).ravel() * (zk - np.array([1.0, 0.0]) @ FN @ xn_c)
    ec = max(ec, np.max(np.abs(N @ xn_c - x)))
check("eq17", "003 reading (x = N x_N, h_N = [1,0], g_N = N^-1 g, d_N = N^-1 d = [T^2/2,T^2]) is consistent",
      ec < 1e-9 and np.allclose(dN3, [T**2 / 2, T**2]), f"max deviation {ec:.2e}")

# ----------------------------------------------------------------------------
# (9): scalar Riccati equations
# ----------------------------------------------------------------------------
mx = 0.0
for r in R_GRID:
    P = ref_PN(r)
    p11, p12, p22 = P[0, 0], P[0, 1], P[1, 1]
    res = [p11 / (1 - p11) - (p11 + 2 * p12 + p22 + r),
           p12 / (1 - p11) - (p12 + p22 + 2 * r),
           (p22 - p11 * p22 + p12**2) / (1 - p11) - (p22 + 4 * r)]
    scale = max(1.0, p11 / (1 - p11), p22 + 4 * r)
    mx = max(mx, max(abs(x) for x in res) / scale)
check("eq9", "DARE solution satisfies the three scalar equations (9), r=1e-9..1e3",
      mx < 1e-8, f"max scaled residual {mx:.2e}")

# ----------------------------------------------------------------------------
# (10), (11): quartic and factorisation (mpmath, 50 digits)
# ----------------------------------------------------------------------------
def quartic(r):
    return [1, 2 * r, r * (r - 18), 2 * r * (16 - r), r * (r - 16)]


worst_fact = mp.mpf(0)
worst_root = mp.mpf(0)
for r in [mp.mpf("2.5e-7"), mp.mpf("0.01"), mp.mpf("0.1"), mp.mpf(3), mp.mpf(4),
          mp.mpf(16), mp.mpf(25), mp.mpf(1000)]:
    a, bb = r + 4 * mp.sqrt(r), r - 4 * mp.sqrt(r)
    prod = [1, a + bb, a * bb - a - bb, -2 * a * bb, a * bb]
    worst_fact = max(worst_fact, max(abs(u - v) for u, v in zip(prod, quartic(r))))
    Pm = mp_riccati(r)
    roots = mp.polyroots(quartic(r), maxsteps=200, extraprec=200)
    worst_root = max(worst_root, min(abs(rt - Pm[0, 0]) for rt in roots))
check("eq10", "p11 of the brute-force 50-digit Riccati limit is a root of quartic (10)",
      worst_root < mp.mpf("1e-25"), f"min |root - p11| worst case {mp.nstr(worst_root, 3)}")
check("eq11", "(11) product of quadratics equals (10) coefficient-wise (50 digits, r incl. 4, 16)",
      worst_fact < mp.mpf("1e-40"), f"max coefficient difference {mp.nstr(worst_fact, 3)}")


# uniqueness of the positive-definite root, and which factor it comes from
def candidate_P(x, r):
    p12 = (x**2 + r * (1 - x)) / (2 - x)
    p22 = x * p12 / (1 - x) - 2 * r
    return p12, p22


uniq_ok = True
first_factor_ok = True
for r in list(R_GRID) + [16.0, 20.0, 100.0, 1e3, 1e4]:
    rts = np.roots(quartic(r))
    pd = []
    for x in rts:
        if abs(x.imag) > 1e-9 or abs(x.real - 1) < 1e-12 or abs(x.real - 2) < 1e-12:
            continue
        x = x.real
        p12, p22 = candidate_P(x, r)
        if x > 0 and x * p22 - p12**2 > 1e-12 * max(1, abs(p22)):
            pd.append(x)
    if len(pd) != 1:
        uniq_ok = False
    elif rel(pd[0], ref_PN(r)[0, 0]) > 1e-7 or rel(pd[0], p11_printed(r)) > 1e-7:
        first_factor_ok = False
check("eq11/12", "exactly one real root of (10) gives a PD P_N (r=1e-9..1e4 incl. r>16 where all 4 roots real)",
      uniq_ok)
check("eq11/12", "that root is the '+' root of the first factor x^2+(r+4sqrt r)x-(r+4sqrt r), = DARE p11",
      first_factor_ok)

# ----------------------------------------------------------------------------
# (12), (13), (14)
# ----------------------------------------------------------------------------
e11 = e12a = e12b = e22 = e22s = 0.0
for r in R_GRID:
    P = ref_PN(r)
    p11 = p11_printed(r)
    e11 = max(e11, rel(p11, P[0, 0]))
    e12a = max(e12a, rel(p12_000(p11, r), P[0, 1]))
    e12b = max(e12b, rel(p12_003(p11, r), P[0, 1]))
    e22 = max(e22, rel(p22_printed(p11, p12_003(p11, r), r), P[1, 1]))
    e22s = max(e22s, max(rel(u, v) for u, v in zip(gains_stable(r), (P[0, 0], P[0, 1], P[1, 1]))))
check("eq12", "p11 = ((r+4sqrt r)/2)(sqrt(1+4/(r+4sqrt r))-1) vs DARE, r=1e-9..1e3", e11 < 1e-8,
      f"max rel err {e11:.2e}")
check("eq12", "[printed 000] p12 = (p11^2+r(1-p11))/2 - p11 vs DARE", e12a < 1e-6, expect=False,
      detail=f"max rel err {e12a:.3g} (e.g. r=0.1: {p12_000(p11_printed(0.1), 0.1):.6f} vs {ref_PN(0.1)[0,1]:.6f})")
check("eq12", "[printed 003 = corrected] p12 = (p11^2+r(1-p11))/(2-p11) vs DARE", e12b < 1e-8,
      f"max rel err {e12b:.2e}")
check("eq12", "p22 = p11 p12/(1-p11) - 2r vs DARE", e22 < 1e-7, f"max rel err {e22:.2e}")
check("eq12", "equivalent cancellation-free forms p11=2/(1+s), p12, p22=p12(2p11-p12)/(2(1-p11)) vs DARE",
      e22s < 1e-8, f"max rel err {e22s:.2e}")

# high precision: printed forms in double precision lose accuracy for large r
hp_bad = []
for r in (1e4, 1e8):
    rm = mp.mpf(r)
    am = rm + 4 * mp.sqrt(rm)
    q11 = am / 2 * (mp.sqrt(1 + 4 / am) - 1)
    q12 = (q11**2 + rm * (1 - q11)) / (2 - q11)
    q22 = q11 * q12 / (1 - q11) - 2 * rm
    p11 = p11_printed(r)
    p12 = p12_003(p11, r)
    p22 = p22_printed(p11, p12, r)
    s11, s12, s22 = gains_stable(r)
    hp_bad.append((r, float(abs(p22 - q22) / q22), float(abs(s22 - q22) / q22),
                   float(abs(p12 - q12) / q12), float(abs(s12 - q12) / q12)))
check("eq12-num", "cancellation-free forms accurate to 1e-10 at r=1e4,1e8 (mpmath reference)",
      all(x[2] < 1e-10 and x[4] < 1e-10 for x in hp_bad),
      "; ".join(f"r={x[0]:g}: printed p12 err {x[3]:.1e}, p22 err {x[1]:.1e}; stable p22 err {x[2]:.1e}"
                for x in hp_bad))

# 50-digit brute-force Riccati iteration vs closed form (12), r = 0.1 and GPS r
for rs in ("0.1", "2.5e-7"):
    rm = mp.mpf(rs)
    Pm = mp_riccati(rm)
    am = rm + 4 * mp.sqrt(rm)
    q11 = am / 2 * (mp.sqrt(1 + 4 / am) - 1)
    q12 = (q11**2 + rm * (1 - q11)) / (2 - q11)
    q22 = q11 * q12 / (1 - q11) - 2 * rm
    err = max(abs(Pm[0, 0] - q11) / q11, abs(Pm[0, 1] - q12) / q12, abs(Pm[1, 1] - q22) / q22)
    check("eq12-mp", f"(12) with 003's p12 equals 50-digit Riccati iteration limit, r={rs}",
          err < mp.mpf("1e-30"), f"max rel err {mp.nstr(err, 3)}")

# Kalata (1984) tracking-index relations, lambda = sw T^2/sv = 2 sqrt(r)
mxk = 0.0
for r in R_GRID:
    lam = 2 * np.sqrt(r)
    s = np.sqrt(lam**2 + 8 * lam)
    aK = -(lam**2 + 8 * lam - (lam + 4) * s) / 8
    bK = (lam**2 + 4 * lam - lam * s) / 4
    P = ref_PN(r)
    mxk = max(mxk, rel(aK, P[0, 0]), rel(bK, P[0, 1]))
check("cross", "literature cross-check: Kalata alpha(lambda), beta(lambda) with lambda=2sqrt(r) equal DARE gains",
      mxk < 1e-7, f"max rel err {mxk:.2e}")

# (14) + (4)/(13) by Monte-Carlo simulation in raw units of the GPS model
def simulate(sw, sv, T, alpha, beta, runs=400, steps=3000, burn=300):
    F = np.array([[1.0, T], [0.0, 1.0]])
    x = np.zeros((runs, 2))
    xh = np.zeros((runs, 2))
    s1 = s2 = s12 = 0.0
    n = 0
    for k in range(steps):
        w = RNG.normal(size=runs) * sw
        x = x @ F.T
        x[:, 0] += w * T**2 / 2
        x[:, 1] += w * T
        zk = x[:, 0] + RNG.normal(size=runs) * sv
        xp = xh @ F.T
        e = zk - xp[:, 0]
        xh = xp
        xh[:, 0] += alpha * e
        xh[:, 1] += beta / T * e
        if k >= burn:
            er = x - xh
            s1 += np.sum(er[:, 0] ** 2)
            s2 += np.sum(er[:, 1] ** 2)
            s12 += np.sum(er[:, 0] * er[:, 1])
            n += runs
    return s1 / n, s12 / n, s2 / n


for (sw_, sv_, T_) in [(3.2, 32.0, 0.1), (10.0, 1.0, 0.5)]:
    r = ((sw_ * T_**2 / 2) / sv_) ** 2
    p11, p12, p22 = gains_stable(r)
    v1, v12, v2 = simulate(sw_, sv_, T_, p11, p12)
    e1 = rel(v1 / sv_**2, p11)
    e2 = rel(v2 * T_**2 / sv_**2, p22)
    e3 = rel(v12 * T_ / sv_**2, p12)
    check("eq14-sim", f"simulated filtered errors match sv^2 N P_N N (r={r:.4g}; tol 3%)",
          e1 < 0.03 and e2 < 0.03 and e3 < 0.03,
          f"sigma_t^2/sv^2 = {v1/sv_**2:.5f} vs p11 = {p11:.5f}; "
          f"var(v err) T^2/sv^2 = {v2*T_**2/sv_**2:.4g} vs p22 = {p22:.4g}; cov = {v12*T_/sv_**2:.4g} vs p12 = {p12:.4g}")

# ----------------------------------------------------------------------------
# (15): Kalman gains always give delta = 1/sqrt 2
# ----------------------------------------------------------------------------
mxd = 0.0
for r in R_GRID:
    P = ref_PN(r)
    alpha, beta = P[0, 0], P[0, 1]
    delta = (alpha + beta / 2) / (2 * np.sqrt(beta))
    mxd = max(mxd, abs(delta - 1 / SQ2))
check("eq15", "Kalman (alpha,beta) solve (15) with delta = 1/sqrt2 for every r (1e-9..1e3)", mxd < 1e-8,
      f"max |delta - 0.70710678| = {mxd:.2e}")

# ----------------------------------------------------------------------------
# (16): one-sided noise bandwidth, integral of |H(j 2 pi f)|^2 df / |H(0)|^2
# ----------------------------------------------------------------------------
mxb = 0.0
for (delta, beta) in [(1 / SQ2, 0.375), (1 / SQ2, 0.01), (1 / SQ2, 1.9), (0.3, 0.2), (1.5, 0.8),
                      (0.5, 2.5)]:
    T = 0.1
    wn = np.sqrt(beta) / T
    K = wn * (2 * delta - wn * T)
    H = lambda f: abs((K * (2j * np.pi * f) + wn**2) / ((2j * np.pi * f) ** 2
                      + 2 * delta * wn * (2j * np.pi * f) + wn**2)) ** 2
    val = quad(H, 0, np.inf, epsabs=0, epsrel=1e-12, limit=500)[0]
    mxb = max(mxb, rel(val * T, bnt_printed(beta, delta)))
check("eq16", "B_N T = (sqrt(beta)/(8 delta))(1+(2delta-sqrt(beta))^2) vs quad of |H(j2pi f)|^2, 6 (delta,beta)",
      mxb < 1e-8, f"max rel err {mxb:.2e}")

# (16) describes the continuous prototype; the discrete alpha-beta filter's own
# noise-equivalent bandwidth is VRR/2, VRR = sum of squared impulse response of
# the filtered position = (2a^2+2b-3ab)/(a(4-2a-b)).
def vrr_sum(alpha, beta, n=6000):
    Fd = np.array([[1.0, 1.0], [0.0, 1.0]])
    gd = np.array([alpha, beta])
    x = np.zeros(2)
    s = 0.0
    for k in range(n):
        xp = Fd @ x
        x = xp + gd * ((1.0 if k == 0 else 0.0) - xp[0])
        s += x[0] ** 2
    return s


vr_ok = True
for beta in (0.01, 0.375, 1.0):
    alpha = SQ2 * np.sqrt(beta) - beta / 2
    vrr_cf = (2 * alpha**2 + 2 * beta - 3 * alpha * beta) / (alpha * (4 - 2 * alpha - beta))
    vr_ok &= rel(vrr_sum(alpha, beta), vrr_cf) < 1e-9
check("eq16-disc", "discrete VRR = (2a^2+2b-3ab)/(a(4-2a-b)) vs sum of squared impulse response", vr_ok)
a_c = SQ2 * np.sqrt(0.375) - 0.375 / 2
vrr_c = (2 * a_c**2 + 2 * 0.375 - 3 * a_c * 0.375) / (a_c * (4 - 2 * a_c - 0.375))
a_s = SQ2 * np.sqrt(1e-4) - 1e-4 / 2
vrr_s = (2 * a_s**2 + 2e-4 - 3 * a_s * 1e-4) / (a_s * (4 - 2 * a_s - 1e-4))
check("eq16-disc", "[printed, read as the discrete filter's bandwidth] (16) = VRR/2 of the alpha-beta filter (tol 5%)",
      rel(vrr_c / 2, bnt_printed(0.375, 1 / SQ2)) < 0.05, expect=False,
      detail=f"beta=0.375: VRR/2 = {vrr_c/2:.6f} vs (16) {bnt_printed(0.375, 1/SQ2):.6f} "
      f"(ratio {vrr_c/2/bnt_printed(0.375, 1/SQ2):.4f}); beta=1e-4: ratio {vrr_s/2/bnt_printed(1e-4, 1/SQ2):.5f}")

# closed-form inverse used by the nomograph (r from alpha), text says 'numerically'
inv_ok = True
for r in R_GRID:
    p11, p12, _ = gains_stable(r)
    r_a = (np.sqrt(4 + p11**2 / (1 - p11)) - 2) ** 2
    r_b = p12**2 / (4 * (1 - p11))
    inv_ok &= rel(r_a, r) < 1e-6 and rel(r_b, r) < 1e-8
check("inv", "r = (sqrt(4+alpha^2/(1-alpha))-2)^2 = beta^2/(4(1-alpha)) inverts (12)/(14), r=1e-9..1e3", inv_ok)

# ----------------------------------------------------------------------------
# Ranges / stability
# ----------------------------------------------------------------------------
def stable(alpha, beta):
    return np.max(np.abs(np.roots([1, -(2 - alpha - beta), 1 - alpha]))) < 1 - 1e-12


pts = RNG.uniform([-0.5, -0.5], [2.5, 4.5], size=(20000, 2))
pts = pts[np.abs(pts[:, 1] - (4 - 2 * pts[:, 0])) > 1e-3]
pts = pts[(np.abs(pts[:, 0]) > 1e-3) & (np.abs(pts[:, 0] - 2) > 1e-3) & (np.abs(pts[:, 1]) > 1e-3)]
jury = (pts[:, 0] > 0) & (pts[:, 0] < 2) & (pts[:, 1] > 0) & (pts[:, 1] < 4 - 2 * pts[:, 0])
eig = np.array([stable(a_, b_) for a_, b_ in pts])
check("range", "closed-loop stable  <=>  0<alpha<2, 0<beta<4-2alpha (20000 random points, eigenvalues)",
      np.all(eig == jury))
printed = (pts[:, 0] >= 0) & (pts[:, 0] <= 1)
check("range", "[printed] '0<=alpha<=1 : stability' is the stability condition", np.all(eig == printed),
      expect=False,
      detail=f"counter-examples: (alpha,beta)=(1.3,1.0) stable={stable(1.3, 1.0)}, (0.9,3.0) stable={stable(0.9, 3.0)}")
# in (delta, wnT): stable <=> 0 < wnT < min(1/delta, 4 delta)
dl = RNG.uniform(0.05, 3, 20000)
wt = RNG.uniform(0.0, 4.5, 20000)
keep = (np.abs(wt - np.minimum(1 / dl, 4 * dl)) > 1e-3) & (wt > 1e-3)
dl, wt = dl[keep], wt[keep]
al_ = wt * (2 * dl - wt / 2)
be_ = wt**2
eig2 = np.array([stable(a_, b_) for a_, b_ in zip(al_, be_)])
check("range", "deterministic design (15) is stable <=> 0 < wn T < min(1/delta, 4 delta)",
      np.all(eig2 == (wt < np.minimum(1 / dl, 4 * dl))))
# on the Kalman curve delta = 1/sqrt 2: stable <=> 0<beta<2 <=> 0<alpha<1
bb = np.linspace(1e-4, 2 - 1e-4, 500)
aa = SQ2 * np.sqrt(bb) - bb / 2
ok = all(stable(a_, b_) for a_, b_ in zip(aa, bb)) and np.all((aa > 0) & (aa < 1)) \
    and not stable(SQ2 * np.sqrt(2.05) - 2.05 / 2, 2.05)
rmax = 1e6
g_hi = gains_stable(rmax)
check("range", "on delta=1/sqrt2: stable <=> 0<beta<2 <=> 0<alpha<1; Kalman gains fill it (r->inf: alpha,beta->1,2)",
      ok and g_hi[0] < 1 and g_hi[1] < 2 and g_hi[0] > 0.999 and g_hi[1] > 1.99,
      f"r=1e6: alpha={g_hi[0]:.6f}, beta={g_hi[1]:.6f}")

# ----------------------------------------------------------------------------
# GPS car example
# ----------------------------------------------------------------------------
sw, sv, T = 3.2, 32.0, 0.1
snr = (sw / sv) ** 2
check("gps", "SNR=(sw/sv)^2 = 0.01 and 10 log10 = -20 dB (arithmetic)",
      abs(snr - 0.01) < 1e-15 and abs(10 * np.log10(snr) + 20) < 1e-12)
r_gps = ((sw * T**2 / 2) / sv) ** 2
check("gps", "[printed] the example's SNR equals r of (9)", abs(r_gps - snr) / snr < 1e-6, expect=False,
      detail=f"r = ((3.2*0.1^2/2)/32)^2 = {r_gps:.6g} ({10*np.log10(r_gps):.6f} dB), not 0.01")


def design(r):
    p11, p12, p22 = gains_stable(r)
    return p11, p12, bnt_printed(p12, 1 / SQ2)


for rv, lab in ((r_gps, "r(9)=2.5e-7"), (0.01, "r=0.01"), (0.1, "r=0.1")):
    a_, b_, n_ = design(rv)
    P = ref_PN(rv)
    print(f"INFO  [gps] {lab}: alpha={a_:.9f} beta={b_:.9f} BNT={n_:.9f} Bn={n_/T:.7f} Hz "
          f"g2={b_/T:.7f} sigma={sv*np.sqrt(a_):.7f} ft  (DARE alpha={P[0,0]:.9f} beta={P[0,1]:.9f})")

a_g, b_g, n_g = design(r_gps)
check("gps", "[printed] alpha=0.68, beta=0.375, BNT=0.175 are the design for r of (9)",
      abs(a_g - 0.68) < 0.02 and abs(b_g - 0.375) < 0.02, expect=False,
      detail=f"r=2.5e-7 gives alpha={a_g:.6f}, beta={b_g:.6g}, BNT={n_g:.6f}")
a_1, b_1, n_1 = design(0.01)
check("gps", "[printed] alpha=0.68, beta=0.375, BNT=0.175 are the design for r=0.01 (-20 dB on 10log10)",
      abs(a_1 - 0.68) < 0.02 and abs(b_1 - 0.375) < 0.02, expect=False,
      detail=f"r=0.01 gives alpha={a_1:.6f}, beta={b_1:.6f}, BNT={n_1:.6f}")
a_2, b_2, n_2 = design(0.1)
check("gps", "chart numbers match r=0.1 (-20 dB on a 20log10(r) axis) within chart-reading tol (4%)",
      rel(a_2, 0.68) < 0.04 and rel(b_2, 0.375) < 0.04 and rel(n_2, 0.175) < 0.04,
      f"r=0.1: alpha={a_2:.6f} ({100*(a_2/0.68-1):+.2f}%), beta={b_2:.6f} ({100*(b_2/0.375-1):+.2f}%), "
      f"BNT={n_2:.6f} ({100*(n_2/0.175-1):+.2f}%)")
r_a = brentq(lambda r: design(r)[0] - 0.68, 1e-4, 10, xtol=1e-15)
r_b = brentq(lambda r: design(r)[1] - 0.375, 1e-4, 10, xtol=1e-15)
r_n = brentq(lambda r: design(r)[2] - 0.175, 1e-4, 10, xtol=1e-15)
fit = minimize_scalar(lambda lr: (design(10**lr)[0] / 0.68 - 1) ** 2 + (design(10**lr)[1] / 0.375 - 1) ** 2
                      + (design(10**lr)[2] / 0.175 - 1) ** 2, bounds=(-3, 0), method="bounded",
                      options={"xatol": 1e-10})
r_fit = 10**fit.x
print(f"INFO  [gps] r implied by alpha=0.68: {r_a:.6g} ({10*np.log10(r_a):.4f} dB); by beta=0.375: {r_b:.6g} "
      f"({10*np.log10(r_b):.4f} dB); by BNT=0.175: {r_n:.6g} ({10*np.log10(r_n):.4f} dB); "
      f"least-squares (rel.) fit: {r_fit:.6g} ({10*np.log10(r_fit):.4f} dB, "
      f"{20*np.log10(r_fit):.4f} dB on 20log10)")
check("gps", "all three chart readings imply r in [0.08, 0.12] (10log10 r = -9.2..-11 dB)",
      all(0.08 < x < 0.12 for x in (r_a, r_b, r_n)))
# internal consistency of chart readings with delta=1/sqrt2 (eq 15)
a_from_b = SQ2 * np.sqrt(0.375) - 0.375 / 2
check("gps", "chart beta=0.375 and alpha=0.68 consistent with (15), delta=1/sqrt2 (tol 1%)",
      rel(a_from_b, 0.68) < 0.01, f"alpha(beta=0.375) = {a_from_b:.6f}")
check("gps", "chart BNT=0.175 consistent with (16) at beta=0.375, delta=1/sqrt2 (tol 2%)",
      rel(bnt_printed(0.375, 1 / SQ2), 0.175) < 0.02, f"BNT(beta=0.375) = {bnt_printed(0.375, 1/SQ2):.6f}")
check("gps", "Bn = 0.175/0.1 = 1.75 Hz and g2 = 0.375/0.1 = 3.75 1/s (arithmetic)",
      abs(0.175 / 0.1 - 1.75) < 1e-12 and abs(0.375 / 0.1 - 3.75) < 1e-12)
check("gps", "sigma = 32 sqrt(0.68) = 26.4 ft (arithmetic, 3 s.f.)",
      abs(32 * np.sqrt(0.68) - 26.4) < 0.05, f"32*sqrt(0.68) = {32*np.sqrt(0.68):.6f}")

# ----------------------------------------------------------------------------
dt = time.time() - T0
n_bad = sum(1 for x in _results if not x)
print("=" * 72)
print(f"{len(_results)} verdicts, {n_bad} differ from docs/errata.md; runtime {dt:.1f} s")
sys.exit(0 if n_bad == 0 else 1)
