"""Forward simulation of the play-operator bank: operator-steps per second.

Same input, same thresholds and tilts, same float64 outputs for every
implementation (checked against each other before timing):

* ``scan``  - `smafl_jax.play_scan` under `jax.jit` (one `lax.scan`, carry = bank vector)
* ``assoc`` - `smafl_jax.play_assoc` under `jax.jit` (parallel-in-time clamp composition)
* ``numba`` - compiled double loop (time x operators), single thread: the CPU limit proxy
* ``numpy`` - Python loop over time, numpy vectorised over the bank (the strong plain-numpy loop)

Kernels: ``bank`` returns all ``(T, n)`` operator outputs (what `play` returns);
``weighted`` returns ``sum_i w_i F_i(k)`` (a PI model's forward pass), where our
side is `play_weighted` (weighted sum inside the scan step); ``batch`` runs 16
records at once (`vmap` of `play_weighted` vs a numba loop over records).

The plain-numpy loop is only run up to ``NUMPY_MAX_STEPS`` samples; for longer
records its rate is taken from the longest measured record (its cost is
linear in T: one Python iteration per sample) and the row says so.
"""

from __future__ import annotations

import numpy as np

from ._common import progress, row, time_call, time_calls

RATIO_MEANING = "ours / baseline in operator-steps per second (> 1: ours faster)"
NUMPY_MAX_STEPS = {True: 10_000, False: 100_000}
ASSOC_MAX_WORK = 5e7  # T * n above this would need several GB for the parallel scan's buffers
BATCH = 16


def _numba_kernels():
    import numba

    @numba.njit(cache=False, fastmath=False)
    def bank(u, r, a, y0):
        T, n = u.shape[0], r.shape[0]
        out = np.empty((T, n))
        y = y0.copy()
        for k in range(T):
            uk = u[k]
            for i in range(n):
                v = min(a[i] * (uk + r[i]), y[i])
                v = max(uk - r[i], v)
                y[i] = v
                out[k, i] = v
        return out

    @numba.njit(cache=False, fastmath=False)
    def weighted(u, r, a, w, y0):
        T, n = u.shape[0], r.shape[0]
        out = np.empty(T)
        y = y0.copy()
        for k in range(T):
            uk = u[k]
            acc = 0.0
            for i in range(n):
                v = max(uk - r[i], min(a[i] * (uk + r[i]), y[i]))
                y[i] = v
                acc += w[i] * v
            out[k] = acc
        return out

    @numba.njit(cache=False, fastmath=False)
    def weighted_batch(U, r, a, w, y0):
        out = np.empty(U.shape)
        for b in range(U.shape[0]):
            out[b] = weighted(U[b], r, a, w, y0)
        return out

    return bank, weighted, weighted_batch


def numpy_bank(u, r, a, y0):
    """Plain numpy loop: one Python iteration per sample, vectorised over the bank."""
    lo = u[:, None] - r[None, :]
    hi = a[None, :] * (u[:, None] + r[None, :])
    out = np.empty_like(lo)
    y = y0.copy()
    for k in range(u.shape[0]):
        np.minimum(hi[k], y, out=out[k])
        np.maximum(lo[k], out[k], out=out[k])
        y = out[k]
    return out


def _jax_kernels():
    import jax

    from smafl_jax.models import play_assoc, play_scan, play_weighted

    scan = jax.jit(lambda u, r, a, y0: play_scan(u, r, a, y0))
    assoc = jax.jit(lambda u, r, a, y0: play_assoc(u, r, a, y0))
    weighted = jax.jit(lambda u, r, a, w, y0: play_weighted(u, r, a, w, y0))
    batch = jax.jit(jax.vmap(lambda u, r, a, w, y0: play_weighted(u, r, a, w, y0), in_axes=(0, None, None, None, None)))
    return scan, assoc, weighted, batch


def _signal(rng, T):
    # random reversals between 0 and 1: minor loops of all sizes, the operators' worst case for branch prediction
    knots = rng.uniform(0.0, 1.0, max(T // 50, 2))
    return np.interp(np.linspace(0, len(knots) - 1, T), np.arange(len(knots)), knots)


def _bank_params(n):
    r = np.arange(1, n + 1) / (2.0 * n)
    a = np.geomspace(0.4, 2.5, n)
    return r, a, np.zeros(n)


def _fmt_T(T):
    e = int(round(np.log10(T)))
    return f"1e{e}" if 10**e == T else str(T)


def run(quick: bool = False) -> list[dict]:
    import jax.numpy as jnp

    repeat = 2 if quick else 3
    n_list = (10, 50, 200)
    T_list = (1_000, 10_000, 100_000) if quick else (1_000, 10_000, 100_000, 1_000_000)
    np_cap = NUMPY_MAX_STEPS[quick]
    rng = np.random.default_rng(0)
    nb_bank, nb_weighted, nb_batch = _numba_kernels()
    scan, assoc, weighted, batch = _jax_kernels()
    rows = []
    unit = "op-steps/s"
    numpy_rate = {}  # n -> (rate, T measured at)

    for n in n_list:
        r, a, y0 = _bank_params(n)
        jr, ja, jy0 = jnp.asarray(r), jnp.asarray(a), jnp.asarray(y0)
        for T in T_list:
            u = _signal(rng, T)
            ju = jnp.asarray(u)
            work = n * T
            progress(f"operators: bank n={n} T={_fmt_T(T)}")
            # correctness first: every implementation must give the same numbers
            ref = nb_bank(u, r, a, y0)
            got = np.asarray(scan(ju, jr, ja, jy0))
            if not np.array_equal(got, ref):
                raise RuntimeError(f"scan and numba disagree (n={n}, T={T}): max diff {np.max(np.abs(got - ref))}")
            del got
            mt = 0.3 if T <= 100_000 else None
            fns = {"numba": lambda: nb_bank(u, r, a, y0), "scan": lambda: scan(ju, jr, ja, jy0)}
            if work <= ASSOC_MAX_WORK:
                fns["assoc"] = lambda: assoc(ju, jr, ja, jy0)
            t = time_calls(fns, repeat=repeat, min_total=mt)
            t_nb, t_scan = t["numba"], t["scan"]
            sz = dict(kernel="bank", n_ops=n, steps=T)
            rows.append(
                row(
                    f"bank n={n} T={_fmt_T(T)}: scan vs numba",
                    work / t_scan,
                    work / t_nb,
                    unit,
                    ours_method="scan",
                    baseline_method="numba",
                    ours_s=t_scan,
                    baseline_s=t_nb,
                    **sz,
                )
            )
            if work <= ASSOC_MAX_WORK:
                if T <= 100_000:
                    got = np.asarray(assoc(ju, jr, ja, jy0))
                    if not np.array_equal(got, ref):
                        raise RuntimeError(f"assoc and numba disagree (n={n}, T={T})")
                    del got
                t_as = t["assoc"]
                rows.append(
                    row(
                        f"bank n={n} T={_fmt_T(T)}: assoc vs numba",
                        work / t_as,
                        work / t_nb,
                        unit,
                        ours_method="assoc",
                        baseline_method="numba",
                        ours_s=t_as,
                        baseline_s=t_nb,
                        **sz,
                    )
                )
            else:
                rows.append(
                    row(
                        f"bank n={n} T={_fmt_T(T)}: assoc vs numba",
                        None,
                        work / t_nb,
                        unit,
                        note=f"not run: T*n = {work:.0e} > {ASSOC_MAX_WORK:.0e} (parallel scan buffers need several GB)",
                        ours_method="assoc",
                        baseline_method="numba",
                        baseline_s=t_nb,
                        **sz,
                    )
                )
            del ref
            if T <= np_cap:
                t_np = time_call(lambda: numpy_bank(u, r, a, y0), repeat=1 if T >= 100_000 else repeat)["best_s"]
                numpy_rate[n] = (work / t_np, T)
                note, t_np_row = "", t_np
            else:
                rate, T_meas = numpy_rate[n]
                t_np_row = work / rate
                note = f"numpy rate measured at T={_fmt_T(T_meas)} (linear in T), not run at T={_fmt_T(T)}"
            rows.append(
                row(
                    f"bank n={n} T={_fmt_T(T)}: scan vs numpy loop",
                    work / t_scan,
                    work / t_np_row,
                    unit,
                    note=note,
                    ours_method="scan",
                    baseline_method="numpy",
                    ours_s=t_scan,
                    baseline_s=t_np_row,
                    baseline_extrapolated=bool(note),
                    **sz,
                )
            )

    # weighted sum (a PI model's forward pass) and a batch of records, at one record length
    T = 10_000 if quick else 100_000
    for n in n_list:
        r, a, y0 = _bank_params(n)
        w = rng.uniform(0.0, 1.0, n)
        jr, ja, jy0, jw = (jnp.asarray(x) for x in (r, a, y0, w))
        u = _signal(rng, T)
        ju = jnp.asarray(u)
        work = n * T
        progress(f"operators: weighted n={n} T={_fmt_T(T)}")
        ref = nb_weighted(u, r, a, w, y0)
        got = np.asarray(weighted(ju, jr, ja, jw, jy0))
        if np.max(np.abs(got - ref)) > 1e-9 * max(1.0, np.max(np.abs(ref))):
            raise RuntimeError(f"play_weighted and numba disagree (n={n})")
        t = time_calls(
            {
                "numba": lambda: nb_weighted(u, r, a, w, y0),
                "fused": lambda: weighted(ju, jr, ja, jw, jy0),
                "bank": lambda: scan(ju, jr, ja, jy0) @ jw,
            },
            repeat=repeat,
            min_total=0.3,
        )
        t_nb, t_w, t_bank = t["numba"], t["fused"], t["bank"]
        sz = dict(kernel="weighted", n_ops=n, steps=T)
        rows.append(
            row(
                f"weighted n={n} T={_fmt_T(T)}: fused scan vs numba",
                work / t_w,
                work / t_nb,
                unit,
                ours_method="play_weighted",
                baseline_method="numba",
                ours_s=t_w,
                baseline_s=t_nb,
                **sz,
            )
        )
        rows.append(
            row(
                f"weighted n={n} T={_fmt_T(T)}: fused scan vs scan-then-matmul",
                work / t_w,
                work / t_bank,
                unit,
                ours_method="play_weighted",
                baseline_method="play_scan @ w",
                ours_s=t_w,
                baseline_s=t_bank,
                **sz,
            )
        )

        Tb = T // BATCH * (4 if not quick else 1)
        U = np.stack([_signal(rng, Tb) for _ in range(BATCH)])
        jU = jnp.asarray(U)
        work_b = n * Tb * BATCH
        got = np.asarray(batch(jU, jr, ja, jw, jy0))
        if np.max(np.abs(got - nb_batch(U, r, a, w, y0))) > 1e-9 * max(1.0, np.max(np.abs(got))):
            raise RuntimeError(f"batched play_weighted and numba disagree (n={n})")
        t = time_calls(
            {"numba": lambda: nb_batch(U, r, a, w, y0), "vmap": lambda: batch(jU, jr, ja, jw, jy0)}, repeat=repeat, min_total=0.3
        )
        t_nbb, t_b = t["numba"], t["vmap"]
        rows.append(
            row(
                f"batch {BATCH}x{_fmt_T(Tb)} n={n}: vmap fused scan vs numba",
                work_b / t_b,
                work_b / t_nbb,
                unit,
                ours_method="vmap(play_weighted)",
                baseline_method="numba loop over records",
                ours_s=t_b,
                baseline_s=t_nbb,
                kernel="batch",
                n_ops=n,
                steps=Tb,
                batch=BATCH,
            )
        )
    return rows


def scaling_series(rows):
    """Points for the log-log scaling plot: seconds per call vs T (per method and n) and vs n."""
    pts = []
    for r in rows:
        if r.get("kernel") != "bank":
            continue
        for side in ("ours", "baseline"):
            s = r.get(f"{side}_s")
            if s is None or (side == "baseline" and r.get("baseline_extrapolated")):
                continue
            pts.append({"method": r[f"{side}_method"], "n_ops": r["n_ops"], "steps": r["steps"], "seconds": s})
    # de-duplicate (numba appears in several rows)
    uniq = {(p["method"], p["n_ops"], p["steps"]): p for p in pts}
    return list(uniq.values())
