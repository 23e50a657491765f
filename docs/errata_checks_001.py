#!/usr/bin/env python3
"""Independent numerical checks of Yoon & Hong, "Closed-Form Solution of ECA
Target-Tracking Filter using Position and Velocity Measurements" (paper 001).

Companion of the "Paper 001 (Yoon & Hong)" section of docs/errata.md.
Standalone: numpy, scipy only (abkit is not used); about 1 s.

References computed here, independently of the printed formulas:
scipy.linalg.expm (the continuous model and Van Loan's discretisation),
scipy.linalg.solve_discrete_are, numpy.poly / numpy.linalg.eig of the
Hamiltonian built from its definition, and a Rauch-Tung-Striebel recursion
run to convergence.

Each line prints PASS or FAIL. A FAIL on a line marked "expected FAIL:
erratum" is a documented erratum; the line after it, the corrected form,
must PASS. Exit status 0 iff every verdict matches docs/errata.md.
"""
import math
import sys

import numpy as np
from scipy.linalg import expm, solve_discrete_are

_results = []


def check(item, desc, ok, detail="", *, expect=True):
    ok = bool(ok)
    tag = "" if expect else "  (expected FAIL: erratum)"
    print(f"{'PASS' if ok else 'FAIL'}  [{item}] {desc}{tag}")
    if detail:
        print(f"        {detail}")
    _results.append(ok == expect)


def relmax(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))


CASES = [  # (T, tau, sigma_m, sigma_1, sigma_2)
    (1.0, 5.0, 1.0, 1.0, 2.0),
    (0.5, 1.0, 3.0, 2.0, 0.7),
    (2.0, 3.0, 0.2, 1.5, 1.0),
]


def van_loan(T, tau, q):
    A = np.array([[0, 1, 0], [0, 0, 1], [0, 0, -1 / tau]], float)
    M = np.zeros((6, 6))
    M[:3, :3] = -A
    M[2, 5] = q
    M[3:, 3:] = A.T
    E = expm(M * T)
    Phi = E[3:, 3:].T
    Q = Phi @ E[:3, 3:]
    return Phi, (Q + Q.T) / 2


def singer_qij(T, tau):
    """Singer (1970) q_ij with alpha = 1/tau (ref [1] of the paper; not printed there)."""
    al = 1 / tau
    e1, e2 = math.exp(-al * T), math.exp(-2 * al * T)
    aT = al * T
    q11 = (1 - e2 + 2 * aT + 2 * aT**3 / 3 - 2 * aT**2 - 4 * aT * e1) / (2 * al**5)
    q12 = (e2 + 1 - 2 * e1 + 2 * aT * e1 - 2 * aT + aT**2) / (2 * al**4)
    q13 = (1 - e2 - 2 * aT * e1) / (2 * al**3)
    q22 = (4 * e1 - 3 - e2 + 2 * aT) / (2 * al**3)
    q23 = (e2 + 1 - 2 * e1) / (2 * al**2)
    q33 = (1 - e2) / (2 * al)
    return np.array([[q11, q12, q13], [q12, q22, q23], [q13, q23, q33]])


def setup(T, tau, sm, s1, s2, dare=True):
    th = T / tau
    x, y = math.exp(-th), math.exp(th)
    a1, a2 = th - 1 + x, th + 1 - y
    q = 2 * sm**2 / tau
    Phi, Q = van_loan(T, tau, q)
    qq = Q / q
    H = np.array([[1.0, 0, 0], [0, 1, 0]])
    R = np.diag([s1**2, s2**2])
    Fit = np.linalg.inv(Phi).T
    M = H.T @ np.linalg.solve(R, H)
    Hf = np.block([[Fit, Fit @ M], [Q @ Fit, Phi + Q @ Fit @ M]])
    P = solve_discrete_are(Phi.T, H.T, Q, R) if dare else None
    return dict(T=T, tau=tau, th=th, x=x, y=y, a1=a1, a2=a2, q=q, qq=qq, Phi=Phi, Q=Q, H=H, R=R, Hf=Hf, P=P, s1=s1, s2=s2)


def printed_pieces(d, fixed):
    T, tau, th, x, y, a1, a2, q = (d[k] for k in "T tau th x y a1 a2 q".split())
    qq, s1, s2 = d["qq"], d["s1"], d["s2"]
    q11, q12, q13, q22, q23, q33 = qq[0, 0], qq[0, 1], qq[0, 2], qq[1, 1], qq[1, 2], qq[2, 2]
    U1 = q * (q11 - tau * th * q12 - tau**2 * a2 * q13)
    U2 = q * (q12 - tau * th * q22 - tau**2 * a2 * q23)
    U3 = q * (q13 - tau * th * q23 - tau**2 * a2 * (q33 if fixed else q23))
    S1 = q * (q12 + tau * (1 - y) * q13)
    S2 = q * (q22 + tau * (1 - y) * q23)
    S3 = q * (q23 + tau * (1 - y) * (q33 if fixed else q23))
    Hf = np.array(
        [
            [1, 0, 0, 1 / s1**2, 0, 0],
            [-tau * th, 1, 0, -tau * th / s1**2, 1 / s2**2, 0],
            [-(tau**2) * a2, tau * (1 - y), y, -(tau**2) * a2 / s1**2, tau * (1 - y) / s2**2, 0],
            [U1, S1, y * q13 * q, 1 + U1 / s1**2, tau * th + S1 / s2**2, tau**2 * a1],
            [U2, S2, y * q23 * q, U2 / s1**2, 1 + S2 / s2**2, tau * (1 - x)],
            [U3, S3, y * q33 * q, U3 / s1**2, S3 / s2**2, x],
        ]
    )
    ch = math.cosh(th)
    a = -4 - 2 * ch - U1 / s1**2 - S2 / s2**2
    A1 = 2 * (1 + ch) * U1 - tau * th * U2 - tau**2 * a1 * U3 + tau * th * S1 + tau**2 * a2 * y * q13
    A2 = 2 * (1 + ch) * S2 - tau * (1 - x) * S3 - tau * (1 - y) * y * q23
    A3 = U1 * S2 - U2 * S1
    b = 7 + 8 * ch + A1 / s1**2 + A2 / s2**2 + A3 / (s1**2 * s2**2)
    B1 = (
        -2 * (1 + 2 * ch) * U1
        + tau * th * (1 + 2 * ch) * U2
        + tau**2 * ((2 + y) * a1 - th * (1 - x)) * U3
        - tau * th * (1 + 2 * ch) * S1
        + tau**2 * th**2 * S2
        + tau**3 * th * a1 * S3
        + tau**2 * (th * (1 - y) - (2 + x) * a2) * y * q13
        + tau**3 * th * a2 * y * q23
        + tau**4 * a1 * a2 * y * q33
    )
    B2 = -2 * (1 + 2 * ch) * S2 + tau * (1 - x) * (2 + y) * S3 + tau * (2 + x) * (1 - y) * y * q23 - tau**2 * (1 - x) * (1 - y) * y * q33
    B3 = (
        -2 * ch * (U1 * S2 - U2 * S1)
        + tau * (1 - x) * (U1 * S3 - U3 * S1)
        + tau**2 * a1 * (U3 * S2 - U2 * S3)
        - tau * (tau * a2 * S2 + (1 - y) * U2) * y * q13
        + tau * (tau * a2 * S1 + (1 - y) * U1) * y * q23
    )
    c = -8 - 12 * ch + B1 / s1**2 + B2 / s2**2 + B3 / (s1**2 * s2**2)
    return dict(Hf=Hf, a=a, b=b, c=c, U3=U3, S3=S3, A=(A1, A2, A3), B=(B1, B2, B3), ch=ch)


def principal_minor_coeffs(Hm):
    n = Hm.shape[0]
    e2 = sum(np.linalg.det(Hm[np.ix_([i, j], [i, j])]) for i in range(n) for j in range(i + 1, n))
    e3 = sum(
        np.linalg.det(Hm[np.ix_([i, j, k], [i, j, k])]) for i in range(n) for j in range(i + 1, n) for k in range(j + 1, n)
    )
    return -np.trace(Hm), e2, -e3


# ---------------------------------------------------------------------------
for T, tau, sm, s1, s2 in CASES:
    d = setup(T, tau, sm, s1, s2)
    tag = f"T={T}, tau={tau}"
    th, x, y, a1, a2 = d["th"], d["x"], d["y"], d["a1"], d["a2"]
    A = np.array([[0, 1, 0], [0, 0, 1], [0, 0, -1 / tau]])
    Phi2 = np.array([[1, tau * th, tau**2 * a1], [0, 1, tau * (1 - x)], [0, 0, x]])
    check("(2)", f"Phi = expm(A T) ({tag})", relmax(Phi2 + 1e-300, expm(A * T) + 1e-300) < 1e-13)
    Phi3 = np.array([[1, -tau * th, -(tau**2) * a2], [0, 1, tau * (1 - y)], [0, 0, y]])
    check("(3)", f"Phi^-1 as printed ({tag})", np.max(np.abs(Phi3 - np.linalg.inv(Phi2))) < 1e-12)
    Q = d["Q"]
    check("(4)", f"q = 2 sigma_m^2/tau (printed '/r'): Q33 = sigma_m^2 (1 - e^-2theta) ({tag})",
          abs(Q[2, 2] / (sm**2 * (1 - x * x)) - 1) < 1e-12)
    check("(4)", f"Singer's exact q_ij (ref [1]) = Van Loan Q / q ({tag})", relmax(singer_qij(T, tau), d["qq"]) < 1e-11,
          f"max rel diff {relmax(singer_qij(T, tau), d['qq']):.1e}")
    pp = printed_pieces(d, fixed=False)
    pc = printed_pieces(d, fixed=True)
    err_p = np.max(np.abs(pp["Hf"] - d["Hf"])) / np.max(np.abs(d["Hf"]))
    err_c = np.max(np.abs(pc["Hf"] - d["Hf"])) / np.max(np.abs(d["Hf"]))
    check("(9)", f"H_f as printed (U3, S3 with q23 in their last term) ({tag})", err_p < 1e-12, f"max rel err {err_p:.2e}",
          expect=False)
    check("(9)", f"H_f corrected (U3, S3 with q33) ({tag})", err_c < 1e-12, f"max rel err {err_c:.2e}")
    poly = np.poly(d["Hf"])
    check("(12)", f"char. poly of H_f is palindromic ({tag})", np.max(np.abs(poly - poly[::-1])) < 1e-9 * np.max(np.abs(poly)))
    check("(12)", f"a as printed ({tag})", abs(pc["a"] / poly[1] - 1) < 1e-10)
    check("(12)", f"b as printed (with corrected U3, S3) ({tag})", abs(pc["b"] / poly[2] - 1) < 1e-8,
          f"printed {pc['b']:.10g}, numpy.poly {poly[2]:.10g}", expect=False)
    check("(12)", f"c as printed (with corrected U3, S3) ({tag})", abs(pc["c"] / poly[3] - 1) < 1e-8,
          f"printed {pc['c']:.10g}, numpy.poly {poly[3]:.10g}", expect=False)
    a_, b_, c_ = principal_minor_coeffs(d["Hf"])
    check("(12)", f"corrected: b = E2, c = -E3 (principal minors of H_f) ({tag})",
          abs(b_ / poly[2] - 1) < 1e-10 and abs(c_ / poly[3] - 1) < 1e-10)
    # Which pieces of b, c are right: b, c are affine in u = 1/s1^2, v = 1/s2^2 and uv.
    polys = {}
    for u, v in [(0, 0), (1, 0), (0, 1), (1, 1)]:
        dd = setup(T, tau, sm, 1 / math.sqrt(u) if u else 1e150, 1 / math.sqrt(v) if v else 1e150, dare=False)
        polys[(u, v)] = np.poly(dd["Hf"])
    P0 = polys[(0, 0)]
    Pu, Pv = polys[(1, 0)] - P0, polys[(0, 1)] - P0
    Puv = polys[(1, 1)] - polys[(1, 0)] - polys[(0, 1)] + P0
    d1 = setup(T, tau, sm, 1.0, 1.0)
    p1 = printed_pieces(d1, fixed=True)
    ch = p1["ch"]
    check("(12)", f"constant parts 7 + 8 cosh(theta), -8 - 12 cosh(theta) and A3 ({tag})",
          abs(P0[2] / (7 + 8 * ch) - 1) < 1e-10 and abs(P0[3] / (-8 - 12 * ch) - 1) < 1e-10 and abs(Puv[2] / p1["A"][2] - 1) < 1e-6)
    bad = [n for n, got, want in zip(("A1", "A2", "B1", "B2", "B3"), (*p1["A"][:2], *p1["B"]), (Pu[2], Pv[2], Pu[3], Pv[3], Puv[3]))
           if abs(got / want - 1) > 1e-6]
    check("(12)", f"A1, A2, B1, B2, B3 as printed ({tag})", not bad, f"wrong: {', '.join(bad)}", expect=False)
    # (13)-(16)
    lam = np.linalg.eigvals(d["Hf"])
    out = lam[np.abs(lam) > 1]
    X = out + 1 / out
    al, be, ga = -poly[1], poly[2] - 3, -poly[3] + 2 * poly[1]
    check("(14)", f"alpha = -a, beta = b - 3, gamma = -c + 2a ({tag})",
          abs(X.sum() - al) < 1e-9 * abs(al) and abs((X[0] * X[1] + X[1] * X[2] + X[0] * X[2]) - be) < 1e-9 * abs(be)
          and abs(np.prod(X) - ga) < 1e-9 * abs(ga))
    X3 = X[np.argmin(np.abs(X.imag))]
    X12 = 0.5 * ((al - X3) + np.array([1, -1]) * np.sqrt((al - X3) ** 2 - 4 * ga / X3 + 0j))
    check("(15)", f"X_1,2 from X_3 ({tag})", np.max(np.min(np.abs(X12[:, None] - X[None, :]), axis=1)) < 1e-8 * np.max(np.abs(X)))
    check("(16)", f"X_i are roots of the cubic ({tag})", np.max(np.abs(X**3 - al * X**2 + be * X - ga)) < 1e-8 * abs(ga))
    # Vaughan: P = W21 W11^-1 from the eigenvectors of the outside eigenvalues.
    w, V = np.linalg.eig(d["Hf"])
    Vo = V[:, np.abs(w) > 1]
    P_v = np.real(Vo[3:] @ np.linalg.inv(Vo[:3]))
    check("(18)", f"P = W21 W11^-1 equals the DARE solution ({tag})", relmax(P_v, d["P"]) < 1e-9, f"{relmax(P_v, d['P']):.1e}")
    # (17): eigenvector components with w1 = 1.
    ok = {"w3": True, "w4": True, "w5": True, "w6p": True, "w6c": True}
    q, qq = d["q"], d["qq"]
    for i in np.where(np.abs(w) > 1)[0]:
        li, v = w[i], V[:, i] / V[0, i]
        w2 = v[1]
        w3 = tau * li * (tau * a2 - (1 - y) * (tau * th + w2)) / (y - li)
        w4 = (li - 1) * s1**2
        w5 = (tau * th * li - (1 - li) * w2) * s2**2
        w6p = (-pc["U3"] * li - pc["S3"] * w2 - w3 * y * qq[2, 2] - pc["S3"] / s2**2 * w5) / (x - li)
        w6c = (-pc["U3"] * li - pc["S3"] * w2 - w3 * y * qq[2, 2] * q - pc["S3"] / s2**2 * w5) / (x - li)
        for k, val, j in (("w3", w3, 2), ("w4", w4, 3), ("w5", w5, 4), ("w6p", w6p, 5), ("w6c", w6c, 5)):
            ok[k] &= abs(val - v[j]) <= 1e-8 * max(abs(v[j]), 1e-300)
    check("(17)", f"w_3i, w_4i, w_5i as printed (given w_2i) ({tag})", ok["w3"] and ok["w4"] and ok["w5"])
    check("(17)", f"w_6i as printed (term w_3i y q33, no q) ({tag})", ok["w6p"], expect=False)
    check("(17)", f"w_6i corrected (w_3i y q q33) ({tag})", ok["w6c"])
    # (7), (8), (22): smoother covariance vs an RTS recursion to convergence.
    Phi, H, R, P = d["Phi"], d["H"], d["R"], d["P"]
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    IKH = np.eye(3) - K @ H
    Pf = IKH @ P @ IKH.T + K @ R @ K.T
    check("(8)", f"Joseph form = (I - K H) P ({tag})", relmax(Pf, IKH @ P) < 1e-10)
    Ag = Pf @ Phi.T @ np.linalg.inv(P)
    Ps = Pf.copy()
    for _ in range(5000):
        Pn = Pf + Ag @ (Ps - P) @ Ag.T
        if np.max(np.abs(Pn - Ps)) < 1e-17:
            break
        Ps = Pn
    lhs = Ps - Ag @ Ps @ Ag.T
    check("(22)", f"RTS limit satisfies P_s - A P_s A' = P_filt - A P A' ({tag})",
          np.max(np.abs(lhs - (Pf - Ag @ P @ Ag.T))) < 1e-12 * np.max(np.abs(Ps)))

# The constant-acceleration limit (theta -> 0, q = sigma_a^2 T).
T = 1.0
qlim = np.array([[T**5 / 20, T**4 / 8, T**3 / 6], [T**4 / 8, T**3 / 3, T**2 / 2], [T**3 / 6, T**2 / 2, T]])
_, Qs = van_loan(T, 1e6, 1.0)
check("limits", "theta -> 0: q_ij -> [[T^5/20, T^4/8, T^3/6], [., T^3/3, T^2/2], [., ., T]]", relmax(Qs, qlim) < 1e-5)

n_bad = sum(1 for r in _results if not r)
print("=" * 72)
print(f"{len(_results)} verdicts, {n_bad} differ from docs/errata.md")
sys.exit(0 if n_bad == 0 else 1)
