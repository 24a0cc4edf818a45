#!/usr/bin/env python3
"""Our Riccati and H2 solvers beside SciPy's and SLICOT's (through slycot).

Reads what `cargo run --release -p design --example riccati_export -- DIR` wrote (the problems,
our solutions and our times), solves every problem again with
`scipy.linalg.solve_{continuous,discrete}_are` and SLICOT SB02OD, the H2 plants with SLICOT
SB10HD, and prints a Markdown table (also written to DIR/riccati_compare.md):

- relative residual of every solver's X, by one definition (the residual over the sum of the
  sizes of the terms the equation adds up, as `lti::riccati` reports it);
- forward error against a reference: SB02OD's solution refined by Newton steps whose
  residual is formed in extended precision (numpy's 80-bit long double);
- time (the fastest of repeated runs), and the exponent of a power-law fit of time against n on
  the random problems;
- the continuous H2 closed-loop norm of our controller against SB10HD's.

Needs numpy, scipy and slycot (`pip install scipy slycot`).
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import slycot


def matrix(rows):
    return np.array(rows, dtype=float)


def residual(kind, a, b, q, r, s, x):
    """‖Res(X)‖_F / Σ‖term‖_F, the definition lti::riccati reports."""
    s = np.zeros_like(b) if s is None else s
    if kind == "care":
        k = np.linalg.solve(r, b.T @ x + s.T)
        ax = a.T @ x
        coupled = (x @ b + s) @ k
        res = ax + ax.T - coupled + q
        terms = np.linalg.norm(q) + 2 * np.linalg.norm(ax) + np.linalg.norm(coupled)
    else:
        k = np.linalg.solve(r + b.T @ x @ b, b.T @ x @ a + s.T)
        axa = a.T @ x @ a
        coupled = (a.T @ x @ b + s) @ k
        res = axa - coupled + q - x
        terms = (
            np.linalg.norm(axa)
            + np.linalg.norm(coupled)
            + np.linalg.norm(q)
            + np.linalg.norm(x)
        )
    res = (res + res.T) / 2
    return np.linalg.norm(res) / terms


LD = np.longdouble


def inverse_ld(m):
    """The inverse of m in extended precision: the double inverse, refined by Newton–Schulz."""
    y = np.linalg.inv(m.astype(float)).astype(LD)
    eye = np.eye(m.shape[0], dtype=LD)
    for _ in range(2):
        y = y + y @ (eye - m @ y)
    return y


def reference(kind, a, b, q, r, s, x):
    """X refined by three Newton steps whose residual is formed in extended precision (x87
    80-bit, 64-bit mantissa): the forward-error reference for problems without a closed form."""
    a, b, q, r = (m.astype(LD) for m in (a, b, q, r))
    s = np.zeros_like(b) if s is None else s.astype(LD)
    x = x.astype(LD)
    for _ in range(3):
        if kind == "care":
            k = inverse_ld(r) @ (b.T @ x + s.T)
            res = a.T @ x + x @ a - (x @ b + s) @ k + q
        else:
            k = inverse_ld(r + b.T @ x @ b) @ (b.T @ x @ a + s.T)
            res = a.T @ x @ a - (a.T @ x @ b + s) @ k + q - x
        res = (res + res.T) / 2
        ac = (a - b @ k).astype(float)
        if kind == "care":
            delta = sla.solve_continuous_lyapunov(ac.T, -res.astype(float))
        else:
            delta = sla.solve_discrete_lyapunov(ac.T, res.astype(float))
        x = x + ((delta + delta.T) / 2).astype(LD)
    return x


def timed(solve, budget_s=0.3, most=25):
    """The solution and the fastest of repeated runs (at least 5, about budget_s): on a shared
    machine noise only adds time, and the export example times ours the same way."""
    times, out = [], None
    while len(times) < 5 or (sum(times) < budget_s and len(times) < most):
        t0 = time.perf_counter()
        out = solve()
        times.append(time.perf_counter() - t0)
    return out, min(times)


def solvers(kind, a, b, q, r, s):
    n, m = b.shape
    dico = "C" if kind == "care" else "D"

    def scipy_solve():
        if kind == "care":
            return sla.solve_continuous_are(a, b, q, r, s=s)
        return sla.solve_discrete_are(a, b, q, r, s=s)

    def slicot_solve():
        kwargs = {} if s is None else {"L": s}
        return slycot.sb02od(n, m, a, b, q, r, dico, **kwargs)[0]

    return {"scipy": scipy_solve, "SB02OD": slicot_solve}


def fmt(v):
    return "–" if v is None else f"{v:.1e}"


def riccati_table(problems):
    rows = [
        "| problem | n | ours: residual | ours: forward error (estimate) | "
        "ours: time (with the estimate) | "
        "scipy: residual | scipy: forward error | scipy: time | SB02OD: residual | "
        "SB02OD: forward error | SB02OD: time |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    fits = {}
    ratios = []
    for p in problems:
        kind = p["kind"]
        a, b, q, r = (matrix(p[k]) for k in ("a", "b", "q", "r"))
        s = None if p["s"] is None else matrix(p["s"])
        ours = p["ours"]
        start = None if "error" in ours else matrix(ours["x"])
        try:
            start = solvers(kind, a, b, q, r, s)["SB02OD"]()
        except Exception:
            pass
        want = None if start is None else reference(kind, a, b, q, r, s, start)

        def err(x):
            if want is None:
                return None
            return float(np.linalg.norm(x.astype(LD) - want) / np.linalg.norm(want))

        cells = [p["name"], str(a.shape[0])]
        if "error" in ours:
            cells += [f"error: {ours['error']}", "–", "–"]
        else:
            x = matrix(ours["x"])
            fe = err(x)
            estimate = f" ({ours['forward_error']:.0e})"
            cells += [
                fmt(residual(kind, a, b, q, r, s, x)),
                (fmt(fe) if fe is not None else "–") + estimate,
                f"{ours['seconds'] * 1e3:.2f} ms ({ours['seconds_with_estimate'] * 1e3:.2f} ms)",
            ]
            fits.setdefault((kind, "ours", p["family"]), []).append((a.shape[0], ours["seconds"]))
        for name, solve in solvers(kind, a, b, q, r, s).items():
            try:
                x, t = timed(solve)
                cells += [fmt(residual(kind, a, b, q, r, s, x)), fmt(err(x)), f"{t * 1e3:.2f} ms"]
                fits.setdefault((kind, name, p["family"]), []).append((a.shape[0], t))
                if name == "SB02OD" and "error" not in ours:
                    ratios.append(
                        f"{p['name']}: ours / SB02OD {ours['seconds'] / t:.2f} "
                        f"({ours['seconds_with_estimate'] / t:.2f} with the estimate)"
                    )
            except Exception as e:  # a solver's refusal is a result too
                cells += [f"error: {str(e)[:40]}", "–", "–"]
        rows.append("| " + " | ".join(cells) + " |")
    exponents = []
    for (kind, name, family), pts in sorted(fits.items()):
        if family != "random" or len(pts) < 3:
            continue
        ns, ts = zip(*pts)
        slope = np.polyfit(np.log(ns), np.log(ts), 1)[0]
        exponents.append(f"{kind} {name}: time ∝ n^{slope:.2f}")
    return rows, ratios + exponents


def h2_table(plants):
    rows = [
        "| plant | n | our ‖T_zw‖₂ | SB10HD's ‖T_zw‖₂ | relative difference |",
        "|---|---:|---:|---:|---:|",
    ]
    for p in plants:
        a, b1, b2, c1, c2, d12, d21 = (
            matrix(p[k]) for k in ("a", "b1", "b2", "c1", "c2", "d12", "d21")
        )
        n, nw, nu = a.shape[0], b1.shape[1], b2.shape[1]
        nz, ny = c1.shape[0], c2.shape[0]
        b = np.hstack([b1, b2])
        c = np.vstack([c1, c2])
        d = np.block([[np.zeros((nz, nw)), d12], [d21, np.zeros((ny, nu))]])
        ak, bk, ck, dk, _ = slycot.sb10hd(n, nw + nu, nz + ny, nu, ny, a, b, c, d)
        # Closed loop w → z with u = K y (K strictly proper: dk = 0).
        acl = np.block([[a, b2 @ ck], [bk @ c2, ak]])
        bcl = np.vstack([b1, bk @ d21])
        ccl = np.hstack([c1, d12 @ ck])
        wc = sla.solve_continuous_lyapunov(acl, -bcl @ bcl.T)
        theirs = float(np.sqrt(np.trace(ccl @ wc @ ccl.T)))
        if "error" in p["ours"]:
            rows.append(f"| {p['name']} | {n} | error: {p['ours']['error']} | {theirs:.12g} | – |")
            continue
        ours = p["ours"]["h2_norm"]
        rows.append(
            f"| {p['name']} | {n} | {ours:.12g} | {theirs:.12g} | {abs(ours / theirs - 1):.1e} |"
        )
    return rows


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: riccati_compare.py DIR (written by the riccati_export example)")
    folder = Path(sys.argv[1])
    problems = json.loads((folder / "problems.json").read_text())
    plants = json.loads((folder / "h2_plants.json").read_text())
    rows, notes = riccati_table(problems)
    text = "\n".join(
        ["### Riccati equations", "", *rows, "", *(f"- {e}" for e in notes), "",
         "### Continuous H2 (SB10HD)", "", *h2_table(plants), ""]
    )
    (folder / "riccati_compare.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
