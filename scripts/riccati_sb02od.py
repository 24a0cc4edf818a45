#!/usr/bin/env python3
"""Golden data for `crates/lti/tests/near_boundary.rs`: two continuous Riccati problems with a
mode a hair off the imaginary axis that the penalty does not see, solved by SLICOT's SB02OD
(through slycot) and by an extended-precision reference.

The problems (n = 6, m = 2, R = I, no cross term): in modal coordinates `A0` has a real mode
at `a = +1e-8` (then `a = -1e-8`), the modes -1, -2, 0.3 and 0.5 ± 1.5i; `Q0 = C0ᵀC0` with the
first column of `C0` zero (the mode at `a` unseen); `B0` standard normal (every mode moved).
A random orthogonal `U` (QR of a seeded Gaussian) hides the structure: `A = U A0 Uᵀ`,
`B = U B0`, `Q = (U C0ᵀ)(C0 Uᵀ)` symmetrised, all rounded to double — the stored numbers are
the problem. The Hamiltonian's pair nearest the axis is then about ±1.4e-8 (the rounding of
`Q` weighs the mode at about 1e-16, as much as `a²`), which double precision cannot tell from
the axis by the eigenvalue's own perturbation bound.

For each problem the script writes `A`, `B`, `Q`, SB02OD's `X`, the reference `X` and
SB02OD's relative error `‖X − X_ref‖_F / ‖X_ref‖_F`. The reference is Newton's method on the
stored data in mpmath at 50 digits (Lyapunov steps by the Kronecker form) from SB02OD's
solution, checked against the stable invariant subspace of the Hamiltonian from mpmath's
eigenvectors at 60 digits. Numbers are written as 17-digit decimals (`%.17e`, which round-trip
to the same double in Rust's `str::parse`).

Usage (slycot, numpy and mpmath; CI does not run it, the file it writes is the golden data):

    python3 -m venv /tmp/slyvenv && /tmp/slyvenv/bin/pip install slycot numpy mpmath
    /tmp/slyvenv/bin/python scripts/riccati_sb02od.py crates/lti/tests/data/near_boundary_care.txt
"""

import sys
from importlib.metadata import version

import mpmath as mp
import numpy as np
from slycot import sb02od

N, M = 6, 2
SEED = 7
COMMAND = "python3 scripts/riccati_sb02od.py crates/lti/tests/data/near_boundary_care.txt"


def modal(a):
    """A0: the mode `a`, then -1, 0.5 ± 1.5i, -2 and 0.3."""
    a0 = np.zeros((N, N))
    a0[0, 0] = a
    a0[1, 1] = -1.0
    a0[2:4, 2:4] = [[0.5, 1.5], [-1.5, 0.5]]
    a0[4, 4] = -2.0
    a0[5, 5] = 0.3
    return a0


def problems():
    rng = np.random.default_rng(SEED)
    u, _ = np.linalg.qr(rng.standard_normal((N, N)))
    b0 = rng.standard_normal((N, M))
    c0 = rng.standard_normal((N, N))
    c0[:, 0] = 0.0
    for a in (1e-8, -1e-8):
        c = c0 @ u.T
        q = c.T @ c
        yield a, u @ modal(a) @ u.T, u @ b0, (q + q.T) / 2


def mp_matrix(x):
    return mp.matrix(x.tolist())


def newton_reference(a, b, q, x0, steps=8):
    """Newton's method at the current mpmath precision; the iterate and each correction's size
    relative to it."""
    n = a.shape[0]
    am, bm, qm = mp_matrix(a), mp_matrix(b), mp_matrix(q)
    g = bm * bm.T
    x = mp_matrix(x0)
    corrections = []
    for _ in range(steps):
        ac = am - g * x
        res = am.T * x + x * am - x * g * x + qm
        # (Acᵀ D + D Ac)[i, j] = Σ_k Ac[k, i] D[k, j] + D[i, k] Ac[k, j]
        k = mp.matrix(n * n, n * n)
        for i in range(n):
            for j in range(n):
                for l in range(n):
                    k[i * n + j, l * n + j] += ac[l, i]
                    k[i * n + j, i * n + l] += ac[l, j]
        d = mp.lu_solve(k, mp.matrix([-res[i, j] for i in range(n) for j in range(n)]))
        delta = mp.matrix(n, n)
        for i in range(n):
            for j in range(n):
                delta[i, j] = (d[i * n + j] + d[j * n + i]) / 2
        x = x + delta
        corrections.append(float(mp.mnorm(delta, "f") / mp.mnorm(x, "f")))
    return x, corrections


def subspace_reference(a, b, q):
    """X = V₂V₁⁻¹ from the eigenvectors of the Hamiltonian's n eigenvalues left of the axis."""
    n = a.shape[0]
    am, bm, qm = mp_matrix(a), mp_matrix(b), mp_matrix(q)
    h = mp.matrix(2 * n, 2 * n)
    g = bm * bm.T
    for i in range(n):
        for j in range(n):
            h[i, j] = am[i, j]
            h[i, n + j] = -g[i, j]
            h[n + i, j] = -qm[i, j]
            h[n + i, n + j] = -am[j, i]
    e, v = mp.eig(h)
    stable = [k for k in range(2 * n) if mp.re(e[k]) < 0]
    assert len(stable) == n, "the Hamiltonian has not n eigenvalues left of the axis"
    nearest = min((mp.re(e[k]) for k in range(2 * n)), key=abs)
    v1, v2 = mp.matrix(n, n), mp.matrix(n, n)
    for c, k in enumerate(stable):
        for i in range(n):
            v1[i, c] = v[i, k]
            v2[i, c] = v[n + i, k]
    x = v2 * mp.inverse(v1)
    return x.apply(mp.re), float(mp.mnorm(x.apply(mp.im), "f")), float(nearest)


def to_numpy(x):
    return np.array(x.tolist(), dtype=float)


def rows(name, x):
    out = [f"{name} {x.shape[0]} {x.shape[1]}"]
    out += [" ".join(f"{v:.17e}" for v in row) for row in x]
    return out


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    body, summary = [], []
    for a, am, bm, qm in problems():
        x_sb, rcond = sb02od(N, M, am, bm, qm, np.eye(M), "C", L=np.zeros((N, M)))[:2]
        mp.mp.dps = 50
        x_ref, corrections = newton_reference(am, bm, qm, x_sb)
        mp.mp.dps = 60
        x_sub, imaginary, nearest = subspace_reference(am, bm, qm)
        mp.mp.dps = 50
        agree = float(mp.mnorm(x_ref - x_sub, "f") / mp.mnorm(x_ref, "f"))
        assert corrections[-1] < 1e-40 and agree < 1e-40 and imaginary < 1e-40, (
            corrections,
            agree,
            imaginary,
        )
        ref = to_numpy(x_ref)
        closed = np.linalg.eigvals(am - bm @ bm.T @ x_sb)
        assert closed.real.max() < 0, "SB02OD's solution does not stabilise"
        error = np.linalg.norm(x_sb - ref) / np.linalg.norm(ref)
        summary.append(
            f"# a = {a:+.0e}: SB02OD error {error:.3e} (RCOND {rcond:.2e}, closed-loop abscissa "
            f"{closed.real.max():.4e}); exact Hamiltonian pair nearest the axis ±{abs(nearest):.6e}; "
            f"reference Newton corrections {', '.join(f'{c:.1e}' for c in corrections[:5])}, …; "
            f"Newton and subspace references agree to {agree:.1e}"
        )
        body += [f"problem {a:.17e}", f"sb02od_error {error:.17e}"]
        body += rows("A", am) + rows("B", bm) + rows("Q", qm)
        body += rows("X_sb02od", x_sb) + rows("X_reference", ref)
    header = [
        "# Golden data for crates/lti/tests/near_boundary.rs (continuous, R = I, no cross term).",
        f"# Written by: {COMMAND}",
        f"# with slycot {version('slycot')} (SLICOT SB02OD), numpy {version('numpy')}, "
        f"mpmath {version('mpmath')}; seed {SEED}.",
        "# sb02od_error: ‖X_sb02od − X_reference‖_F / ‖X_reference‖_F; X_reference: Newton's",
        "# method on the stored data at 50 digits from SB02OD's X, rounded to double.",
    ] + summary
    with open(sys.argv[1], "w", encoding="utf-8") as f:
        f.write("\n".join(header + body) + "\n")
    print("\n".join(summary))


if __name__ == "__main__":
    main()
