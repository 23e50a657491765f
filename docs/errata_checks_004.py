#!/usr/bin/env python3
"""Independent numerical checks of Chen & Chui, "On Near-optimal Linear
Digital Tracking Filters" (paper 004).

Companion of the "Paper 004 (Chen & Chui)" section of docs/errata.md.
Standalone: numpy, scipy, mpmath only (abkit is not used); about 1 s.

References computed here, independently of the printed formulas:
scipy.linalg.solve_discrete_are (white noise), the Kalman
prediction-covariance recursion run to convergence (coloured noise, where
the measurement noise covariance R is 0), mpmath root finding,
scipy.signal.ss2tf and a direct state-space simulation.

Each line prints PASS or FAIL. A FAIL on a line marked "expected FAIL:
erratum" is a documented erratum; the line after it, the corrected form,
must PASS. Exit status 0 iff every verdict matches docs/errata.md.
"""
import sys

import mpmath
import numpy as np
from scipy.linalg import solve_discrete_are
from scipy.signal import lfilter, ss2tf

_results = []


def check(item, desc, ok, detail="", *, expect=True):
    ok = bool(ok)
    tag = "" if expect else "  (expected FAIL: erratum)"
    print(f"{'PASS' if ok else 'FAIL'}  [{item}] {desc}{tag}")
    if detail:
        print(f"        {detail}")
    _results.append(ok == expect)


def close(a, b, rtol=1e-8, atol=1e-10):
    return np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=rtol, atol=atol)


def phi(h):
    return np.array([[1.0, h, h * h / 2], [0.0, 1.0, h], [0.0, 0.0, 1.0]])


H3 = np.array([[1.0, 0.0, 0.0]])

# ---------------------------------------------------------------- white noise
WHITE = [(0.3, 0.2, 0.1, 1.0, 0.7), (0.0, 0.0, 1.0, 1.0, 1.0), (2.0, 0.0, 1e-3, 0.5, 0.3), (0.0, 1.0, 0.01, 2.0, 1.5)]
ok = {k: True for k in ("K", "iv", "v", "vi", "ii_lo", "ii_hi", "i", "Pt", "psd")}
for sp, sv, sa, sm, h in WHITE:
    F = phi(h)
    S = solve_discrete_are(F.T, H3.T, np.diag([sp, sv, sa]), np.array([[sm]]))
    K = F @ S @ H3.T / (S[0, 0] + sm)  # limiting (predictor) gain, Lemma 1
    w = np.linalg.solve(F, K).ravel()
    a, b, g = w[0], w[1] * h, w[2] * h * h  # sec. 2: K = Phi [alpha, beta/h, gamma/h^2]
    ok["K"] &= close(F @ np.array([a, b / h, g / h**2]), K.ravel())
    ok["iv"] &= close((a * a + a * b + a * g / 2 - 2 * b) / (1 - a), sp / sm)
    ok["v"] &= close((b * b - 2 * a * g) / (1 - a) / h**2, sv / sm)
    ok["vi"] &= close(g * g / (1 - a) / h**4, sa / sm)
    tol = 1e-12
    ok["i"] &= 0 < a < 1 and g > 0
    ok["ii_lo"] &= b >= np.sqrt(2 * a * g) - tol
    ok["ii_hi"] &= b <= a / (2 - a) * (a + g / 2) + tol
    Pt = np.array([[a, b, g], [b, b * (a + b + g / 4) - g / 2 * (2 + a), g * (a + b / 2)], [g, g * (a + b / 2), g * (b + g)]])
    D = np.diag([1.0, h, h * h])
    ok["Pt"] &= close(Pt, (1 - a) * D @ S @ D / sm)
    ok["psd"] &= np.linalg.eigvalsh(Pt).min() >= -1e-12
check("Sec. 2", "alpha-beta-gamma gain K_w = Phi_w [alpha, beta/h, gamma/h^2] of the limiting gain (DARE)", ok["K"])
check("Cor. (iv)", "sigma_p/sigma_m = (a^2 + a b + a g/2 - 2 b)/(1 - a)", ok["iv"])
check("Cor. (v)", "sigma_v/sigma_m = (b^2 - 2 a g)/((1 - a) h^2)", ok["v"])
check("Cor. (vi)", "sigma_a/sigma_m = g^2/((1 - a) h^4)", ok["vi"])
check("Cor. (i)", "0 < alpha < 1, gamma > 0 at the Riccati gains", ok["i"])
check("Cor. (ii)", "sqrt(2 a g) <= beta (sigma_v >= 0), equality iff sigma_v = 0", ok["ii_lo"])
check("Cor. (ii)", "beta <= a (a + g/2)/(2 - a) (sigma_p >= 0), equality iff sigma_p = 0", ok["ii_hi"])
check("Cor. (iii)", "P~ = (1 - alpha) D Sigma D / sigma_m (D = diag(1, h, h^2)), as printed", ok["Pt"])
check("Cor. (iii)", "P~ nonnegative definite at the Riccati gains", ok["psd"])

# Lemma 2: sigma_a = 0 -> no stabilising solution.
F = phi(1.0)
try:
    S0 = solve_discrete_are(F.T, H3.T, np.diag([1.0, 1.0, 0.0]), np.array([[1.0]]))
    K0 = S0 @ H3.T / (S0[0, 0] + 1.0)
    rho = max(abs(np.linalg.eigvals((np.eye(3) - K0 @ H3) @ F)))
    lemma2 = rho > 1 - 1e-6
except (np.linalg.LinAlgError, ValueError):
    lemma2 = True
check("Lemma 2", "sigma_a = 0: the DARE has no stabilising solution (closed loop on the unit circle)", lemma2)

# Acceleration-only closed form (sigma_p = sigma_v = 0): 2(1-s)^3 = lam s (1+s).
okcf = True
for lam in (1e-3, 0.3, 1.0, 20.0):
    with mpmath.workdps(40):
        s = mpmath.findroot(lambda s: 2 * (1 - s) ** 3 - lam * s * (1 + s), (0, 1), solver="bisect")
        cf = [float(1 - s * s), float(2 * (1 - s) ** 2), float(2 * (1 - s) ** 3 / (1 + s))]
    S = solve_discrete_are(F.T, H3.T, np.diag([0.0, 0.0, lam**2]), np.array([[1.0]]))
    okcf &= close(cf, (S @ H3.T / (S[0, 0] + 1.0)).ravel(), rtol=1e-7)
check("Cor., sigma_p = sigma_v = 0", "closed form beta = 2(1-s)^2, gamma = 2(1-s)^3/(1+s), 2(1-s)^3 = lam s(1+s) (derived)", okcf)

# ------------------------------------------------------ coloured (Theorem 2)
def coloured_ref(sp, sv, sa, sm, r, h):
    Fc = np.zeros((4, 4))
    Fc[:3, :3] = phi(h)
    Fc[3, 3] = r
    Hc = np.array([[1.0, 0.0, 0.0, 1.0]])
    Q = np.diag([sp, sv, sa, sm])
    S = np.eye(4) * 10.0
    for _ in range(20000):
        s0 = (Hc @ S @ Hc.T).item()
        Sn = Fc @ (S - S @ Hc.T @ Hc @ S / s0) @ Fc.T + Q
        Sn = 0.5 * (Sn + Sn.T)
        if np.max(np.abs(Sn - S)) <= 1e-15 * np.max(np.abs(Sn)):
            S = Sn
            break
        S = Sn
    K = Fc @ S @ Hc.T / (Hc @ S @ Hc.T).item()
    w = np.linalg.solve(Fc, K).ravel()
    return S, Fc, Hc, w[0], w[1] * h, w[2] * h * h, w[3]


def sigma_tilde_printed(a, b, g, th, r):
    rm = r - 1
    s11 = 1 / rm * ((rm - th * r) * a + r / rm * th * b - r * (r + 1) / (2 * rm**2) * th * g)
    s12 = 1 / rm * ((rm - th * r) * b + th * r / rm * g)
    s13 = 1 / rm * (rm - th * r) * g
    s14 = r * th / rm * (a - b / rm + (r + 1) / (2 * rm**2) * g)
    s22 = 0.25 * (4 * a + b) * (b + g) + 0.75 * (b * b - 2 * a * g) - (rm - th * r) / rm * g
    s23 = (a + b / 2) * g
    s24 = r * th / rm * (b - g / rm)
    s33 = (b + g) * g
    s34 = r * th / rm * g
    s44 = 1 / (1 - r * r) * ((r + 1) * (r * th + r - 1) * a + r * (r + 1) / rm * th * b + r * (r + 1) ** 2 / (2 * rm**2) * g - r * r + 1)
    return np.array([[s11, s12, s13, s14], [s12, s22, s23, s24], [s13, s23, s33, s34], [s14, s24, s34, s44]])


COL = [(3.0, 2.0, 1.0, 5.0, 0.6, 0.8), (0.1, 0.5, 1.0, 0.3, -0.4, 1.0), (0.0, 0.2, 2.0, 1.0, 0.9, 0.5)]
names = ("vi", "vii", "viii_p", "viii_c", "s_rest", "s44_p", "s44_c", "iii_p", "iii_c", "v_p", "v_c", "i", "ii", "psd", "closure", "Kc")
ok = {k: True for k in names}
for sp, sv, sa, sm, r, h in COL:
    S, Fc, Hc, a, b, g, th = coloured_ref(sp, sv, sa, sm, r, h)
    rm = r - 1
    ok["Kc"] &= close(Fc @ np.array([a, b / h, g / h**2, th]), (Fc @ S @ Hc.T / (Hc @ S @ Hc.T)).ravel())
    ok["vi"] &= close(h**2 / g**2 * (b * b - 2 * a * g), sv / sa)
    vii = h**4 / (2 * g * g) * ((2 * a + 2 * b + g) * a - 4 * (rm - r * th) / rm * b - 4 * r * th / rm**2 * g)
    ok["vii"] &= close(vii, sp / sa)
    v_expr = (r + 1) * (r * th + r - 1) * a + r * (r + 1) / rm * th * b + r * (r + 1) ** 2 / (2 * rm**2) * g - r * r + 1
    ok["viii_p"] &= close(h**4 / g**2 * (v_expr + r * r * th * th), sm / sa)
    D = np.diag([1.0, h, h * h, 1.0])
    St_true = g * g / (h**4 * sa) * D @ S @ D  # Sigma~ is this scaling of Sigma_c
    St = sigma_tilde_printed(a, b, g, th, r)
    mask = np.ones((4, 4), bool)
    mask[3, 3] = False
    ok["s_rest"] &= close(St[mask], St_true[mask])
    ok["s44_p"] &= close(St[3, 3], St_true[3, 3])
    s44c = th - St[0, 3]
    ok["s44_c"] &= close(s44c, St_true[3, 3])
    ok["viii_c"] &= close(h**4 / g**2 * ((1 - r * r) * s44c + r * r * th * th), sm / sa)
    iii_p = (4 * a + b) * (b + g) + 3 * (b * b - 2 * a * g) - 4 * (r - 1 - th * g) / rm * g
    iii_c = (4 * a + b) * (b + g) + 3 * (b * b - 2 * a * g) - 4 * (r - 1 - th * r) / rm * g
    ok["iii_p"] &= close(iii_p, 4 * St_true[1, 1])
    ok["iii_c"] &= close(iii_c, 4 * St_true[1, 1])
    ok["v_p"] &= close(v_expr, (1 - r * r) * St_true[3, 3])
    ok["v_c"] &= close((1 - r * r) * s44c, (1 - r * r) * St_true[3, 3])
    ok["i"] &= (2 * a + 2 * b + g) * g > 0
    ok["ii"] &= close((rm * (rm - r * th) * a + r * th * b - r * (r + 1) / (2 * rm) * th * g), rm**2 * St_true[0, 0])
    St_c = St.copy()
    St_c[3, 3] = s44c
    ok["psd"] &= np.linalg.eigvalsh(St_c).min() >= -1e-10
    ok["closure"] &= abs(a + th - 1) < 1e-10
check("Thm 2 / sec. 3", "K_c = Phi_c [alpha, beta/h, gamma/h^2, theta] of the limiting gain (R = 0)", ok["Kc"])
check("Thm 2 (vi)", "sigma_v/sigma_a = h^2 (b^2 - 2 a g)/g^2 (printed sigma_v/sigma_z: OCR)", ok["vi"])
check("Thm 2 (vii)", "sigma_p/sigma_a as printed", ok["vii"])
check("Thm 2 (viii)", "sigma_m/sigma_a as printed", ok["viii_p"], expect=False)
check("Thm 2 (viii)", "corrected: sigma_m/sigma_a = h^4/g^2 ((1 - r^2) sigma~44 + r^2 theta^2)", ok["viii_c"])
check("Thm 2 (ix)", "sigma~11 .. sigma~34 as printed = g^2/(h^4 sigma_a) D Sigma_c D", ok["s_rest"])
check("Thm 2 (ix)", "sigma~44 as printed", ok["s44_p"], expect=False)
check("Thm 2 (ix)", "corrected: sigma~44 = theta - sigma~14", ok["s44_c"])
check("Thm 2 (ix)", "corrected Sigma~ nonnegative definite at the Riccati gains", ok["psd"])
check("Thm 2 (iii)", "as printed, (r - 1 - theta gamma), equals 4 sigma~22", ok["iii_p"], expect=False)
check("Thm 2 (iii)", "corrected (r - 1 - theta r): 4 sigma~22", ok["iii_c"])
check("Thm 2 (v)", "printed expression = (1 - r^2) sigma~44", ok["v_p"], expect=False)
check("Thm 2 (v)", "corrected: (1 - r^2) sigma~44 with sigma~44 = theta - sigma~14", ok["v_c"])
check("Thm 2 (i)", "(2a + 2b + g) g > 0 at the Riccati gains", ok["i"])
check("Thm 2 (ii)", "printed (ii) = (r - 1)^2 sigma~11", ok["ii"])
check("Thm 2 (not printed)", "alpha + theta = 1 (R = 0: the filter reproduces z exactly)", ok["closure"])

# Conditions (i)-(v), (ix) are not sufficient: a counterexample with sigma_p < 0.
S, Fc, Hc, a, b, g, th = coloured_ref(0.0, 0.0, 1.0, 2.0, 0.9, 0.5)
b2, r, h = b * 1.01, 0.9, 0.5
St = sigma_tilde_printed(a, b2, g, th, r)
St[3, 3] = th - St[0, 3]
conds = [(2 * a + 2 * b2 + g) * g > 0, (r - 1) ** 2 * St[0, 0] > 0, St[1, 1] >= 0, St[2, 2] >= 0, St[3, 3] >= 0, np.linalg.eigvalsh(St).min() >= 0]
vii = h**4 / (2 * g * g) * ((2 * a + 2 * b2 + g) * a - 4 * (r - 1 - r * th) / (r - 1) * b2 - 4 * r * th / (r - 1) ** 2 * g)
check("Thm 2 'iff'", "(i)-(v), (ix) sufficient: they hold yet sigma_p/sigma_a < 0", not (all(conds) and vii < 0), f"sigma_p/sigma_a = {vii:.4g}", expect=False)
check("Thm 2 'iff'", "completed by (vi), (vii), (viii) >= 0 (the noise ratios are variances)", all(conds) and vii < 0)

# ----------------------------------------------------------------- Theorem 3
rng = np.random.default_rng(4)
ok = {k: True for k in ("A", "a1_p", "a1_c", "a234", "pos", "vel", "acc_p", "acc_c", "noise", "sim")}
for _ in range(5):
    a, b, g, th, r, h = rng.uniform(0.1, 0.9, 6)
    Fc = np.zeros((4, 4))
    Fc[:3, :3] = phi(h)
    Fc[3, 3] = r
    Hrow = np.array([1.0, 0.0, 0.0, 1.0]) @ Fc
    w = np.array([a, b / h, g / h**2, th])
    A = Fc - np.outer(w, Hrow)
    Ap = np.array(
        [
            [1 - a, (1 - a) * h, 0.5 * (1 - a) * h * h, -a * r],
            [-b / h, 1 - b, (1 - 0.5 * b) * h, -b * r / h],
            [-g / h**2, -g / h, 1 - 0.5 * g, -g * r / h**2],
            [-th, -th * h, -0.5 * th * h * h, (1 - th) * r],
        ]
    )
    ok["A"] &= close(A, Ap, atol=1e-12)
    den = np.poly(A)
    a1p = -a - b - g / 2 + (th - 1) * r + 3
    a1c = -a - b - g / 2 + (1 - th) * r + 3
    a2 = 2 * a + b - g / 2 + (a + b + g / 2 + 3 * th - 3) * r - 3
    a3 = -a + (-2 * a - b + g / 2 - 3 * th + 3) * r + 1
    a4 = (a + th - 1) * r
    ok["a1_p"] &= close(-den[1], a1p)
    ok["a1_c"] &= close(-den[1], a1c)
    ok["a234"] &= close(-den[2:], [a2, a3, a4])
    nums = [ss2tf(A, w[:, None], A[[i], :], np.array([[w[i]]]))[0].ravel() for i in range(4)]
    ok["pos"] &= close(nums[0][:4], [a, -2 * a - r * a + b + g / 2, a - b + g / 2 + (2 * a - b - g / 2) * r, -(a - b + g / 2) * r])
    ok["vel"] &= close(nums[1][:4], np.array([b, -((2 + r) * b - g), b - g + (2 * b - g) * r, -(b - g) * r]) / h)
    ok["acc_p"] &= close(nums[2][:4], g / h**2 * np.array([1, -(2 + g), 1 + 2 * r, -r]))
    acc_c = g / h**2 * np.array([1, -(2 + r), 1 + 2 * r, -r])
    ok["acc_c"] &= close(nums[2][:4], acc_c)
    ok["noise"] &= close(nums[3][:4], th * np.array([1, -3, 3, -1]))
    z = rng.normal(size=40).cumsum()
    y = np.zeros(4)
    ref = np.empty((4, z.size))
    for k in range(z.size):
        y = A @ y + w * z[k]
        ref[:, k] = y
    dc = np.array([1, -a1c, -a2, -a3, -a4])
    ok["sim"] &= close(lfilter(acc_c, dc, z), ref[2], rtol=1e-7, atol=1e-7)
check("Thm 3, matrix A", "A = Phi_c - w H' Phi_c as printed", ok["A"])
check("Thm 3, a1", "a1 = -a - b - g/2 + (theta - 1) r + 3 as printed", ok["a1_p"], expect=False)
check("Thm 3, a1", "corrected: a1 = -a - b - g/2 + (1 - theta) r + 3 (= trace A)", ok["a1_c"])
check("Thm 3, a2-a4", "a2, a3, a4 as printed", ok["a234"])
check("Thm 3 (i)", "position numerator as printed", ok["pos"])
check("Thm 3 (ii)", "velocity numerator as printed", ok["vel"])
check("Thm 3 (iii)", "acceleration numerator as printed, -(2 + gamma) z_k-1", ok["acc_p"], expect=False)
check("Thm 3 (iii)", "corrected: gamma/h^2 [1, -(2 + r), 1 + 2r, -r]", ok["acc_c"])
check("Thm 3 (iv)", "noise numerator theta [1, -3, 3, -1] as printed", ok["noise"])
check("Thm 3", "lfilter with the corrected coefficients = state-space simulation", ok["sim"])

n_bad = sum(1 for r in _results if not r)
print("=" * 72)
print(f"{len(_results)} verdicts, {n_bad} differ from docs/errata.md")
sys.exit(0 if n_bad == 0 else 1)
