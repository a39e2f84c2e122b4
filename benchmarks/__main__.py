"""Collector: run every benchmark section, write the Markdown table, JSON and scaling plot."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
import traceback
from pathlib import Path

from ._common import machine, progress

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# (section key, module, title, ratio meaning when the module does not say)
SECTIONS = [
    ("operators", "bench_operators", "1. Forward simulation of the play-operator bank (issue 2)"),
    ("fit", "bench_fit", "2a. Identification vs scipy.optimize.least_squares (numpy model)"),
    ("sysid", "bench_sysid", "2b. Identification vs jax-sysid"),
    ("emcee", "bench_emcee", "3. emcee log-probability evaluations"),
    ("control", "bench_control", "4. Closed-loop sweeps"),
    ("parallel_time", "bench_parallel_time", "5. Parallel-in-time forward pass: compile and run time by method (issue 15)"),
    ("default_fit", "bench_default_fit", "6. Default `smafl fit` wall time on a 30 000-sample record (issue 18)"),
]
DEFAULT_RATIO = "as defined by the section (see its module docstring)"
DOCS_MARK = "<!-- section:performance -->"
DOCS_END = "<!-- /section:performance -->"


def _load(modname):
    """Import ``benchmarks.<modname>``; None (and the reason) when it is missing or broken."""
    if not (HERE / f"{modname}.py").exists():
        return None, f"{modname}.py not present"
    try:
        return importlib.import_module(f"benchmarks.{modname}"), None
    except Exception as exc:  # a broken section must not stop the others
        return None, f"import failed: {type(exc).__name__}: {exc}"


def _valid_rows(rows):
    if not isinstance(rows, list):
        raise TypeError(f"run() returned {type(rows).__name__}, expected list of dicts")
    for i, r in enumerate(rows):
        if not isinstance(r, dict) or not {"name", "ours", "baseline", "unit"} <= set(r):
            raise TypeError(f"row {i} lacks name/ours/baseline/unit: {r!r}")
    return rows


def run_section(key, modname, title, quick):
    mod, why = _load(modname)
    entry = {"title": title, "module": modname, "quick": quick, "rows": [], "status": "skipped", "note": why or ""}
    if mod is None:
        progress(f"{key}: skipped ({why})")
        return entry
    entry["ratio_meaning"] = getattr(mod, "RATIO_MEANING", DEFAULT_RATIO)
    progress(f"{key}: running {modname}.run(quick={quick})")
    t0 = time.perf_counter()
    try:
        entry["rows"] = _valid_rows(mod.run(quick=quick))
        entry["status"] = "ok"
    except Exception as exc:  # record the failure and carry on with the next section
        entry["status"] = "failed"
        entry["note"] = f"{type(exc).__name__}: {exc}"
        entry["traceback"] = traceback.format_exc()
        progress(f"{key}: FAILED: {entry['note']}")
    entry["seconds"] = time.perf_counter() - t0
    entry["machine"] = machine()
    if key == "operators" and entry["status"] == "ok":
        entry["scaling"] = mod.scaling_series(entry["rows"])
    return entry


def _fmt(x):
    if x is None:
        return "-"
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return str(x)
    if x == 0:
        return "0"
    a = abs(x)
    return f"{x:.3g}" if 1e-3 <= a < 1e5 else f"{x:.2e}"


def _machine_line(m):
    return (
        f"{m['date_utc']}; {m['cpu']}, {m['cpus_usable']} usable CPU cores of {m['cpu_count']}, "
        f"{m['memory_gib']} GiB RAM; {m['os']}; Python {m['python']}, jax {m['jax']} ({m['jax_devices']}), "
        f"numpy {m['numpy']}, numba {m['numba']}; load average during the run {m.get('loadavg', '?')}"
    )


def markdown(doc):
    lines = [
        "# smafl-jax benchmarks",
        "",
        f"Command: `{doc['command']}` (from the repository root).",
        "",
        f"Machine: {_machine_line(doc['machine'])}.",
        "",
        "Every ratio is measured side by side in the same run on that machine; compile time is excluded "
        "(warm-up call, then best of N wall-clock times) unless a row says otherwise.",
        "",
    ]
    for key, _, _title in SECTIONS:
        sec = doc["sections"].get(key)
        if sec is None:
            continue
        lines += [f"## {sec['title']}", ""]
        if sec["status"] != "ok":
            lines += [f"Not run: {sec['note']}", ""]
            continue
        when = sec["machine"]["date_utc"]
        lines += [
            f"Ratio: {sec.get('ratio_meaning', DEFAULT_RATIO)}. Section took {sec['seconds']:.0f} s"
            f"{' (quick mode)' if sec['quick'] else ''}, finished {when}.",
            "",
            "| benchmark | ours | baseline | ratio | unit | note |",
            "| --- | ---: | ---: | ---: | --- | --- |",
        ]
        for r in sec["rows"]:
            note = str(r.get("note", "")).replace("|", "\\|")
            name = str(r["name"]).replace("|", "\\|")
            lines.append(
                f"| {name} | {_fmt(r['ours'])} | {_fmt(r['baseline'])} | {_fmt(r.get('ratio'))} | {r['unit']} | {note} |"
            )
        lines.append("")
    lines += ["Scaling (log-log): `scaling.png` beside this file.", ""]
    return "\n".join(lines)


def scaling_plot(doc, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from smafl_jax import atomic_savefig

    ops = doc["sections"].get("operators", {}).get("scaling", [])
    extra = {}
    for key, sec in doc["sections"].items():
        for r in sec.get("rows", []):
            if {"scale_series", "scale_x", "scale_seconds"} <= set(r):
                extra.setdefault(r.get("scale_xlabel", "size"), []).append(
                    (f"{key}: {r['scale_series']}", r["scale_x"], r["scale_seconds"])
                )
    n_panels = (2 if ops else 0) + len(extra)
    if n_panels == 0:
        return False
    fig, axes = plt.subplots(1, n_panels, figsize=(5.2 * n_panels, 4.2), squeeze=False)
    axes = list(axes[0])
    styles = {"scan": "C0", "assoc": "C1", "numba": "C2", "numpy": "C3"}
    if ops:
        ax = axes.pop(0)
        for method, color in styles.items():
            for n, ls in zip((10, 50, 200), (":", "--", "-")):
                pts = sorted((p["steps"], p["seconds"]) for p in ops if p["method"] == method and p["n_ops"] == n)
                if pts:
                    ax.loglog(*zip(*pts), ls, color=color, marker="o", ms=3, label=f"{method} n={n}")
        ax.set(xlabel="record length T (steps)", ylabel="seconds per call", title="operator bank: cost vs T")
        ax.legend(fontsize=6, ncol=2)
        ax = axes.pop(0)
        Ts = sorted({p["steps"] for p in ops})
        T_ref = 100_000 if 100_000 in Ts else Ts[-1]
        for method, color in styles.items():
            pts = sorted((p["n_ops"], p["seconds"]) for p in ops if p["method"] == method and p["steps"] == T_ref)
            if pts:
                ax.loglog(*zip(*pts), "-", color=color, marker="o", label=method)
        ax.set(xlabel="operators n", ylabel="seconds per call", title=f"operator bank: cost vs n (T={T_ref:g})")
        ax.legend(fontsize=7)
    for xlabel, pts in extra.items():
        ax = axes.pop(0)
        for series in sorted({p[0] for p in pts}):
            xy = sorted((x, s) for name, x, s in pts if name == series)
            ax.loglog(*zip(*xy), marker="o", label=series)
        ax.set(xlabel=xlabel, ylabel="seconds", title=f"cost vs {xlabel}")
        ax.legend(fontsize=7)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=120)
    plt.close(fig)
    return True


def update_docs(doc, page):
    """Replace the generated part of docs/performance.md (between its markers) with the summary tables.

    The README keeps a short summary by hand; the hand-written history around the markers is left alone."""
    from smafl_jax import atomic_write_text

    text = page.read_text()
    if DOCS_MARK not in text:
        raise SystemExit(f"{page}: marker {DOCS_MARK} not found")
    body = docs_section(doc)
    head, rest = text.split(DOCS_MARK, 1)
    if DOCS_END in rest:
        rest = rest.split(DOCS_END, 1)[1]
    else:  # first time: the section ends where the next heading or marker starts
        cut = [i for i in (rest.find("\n## "), rest.find("\n<!-- section:")) if i >= 0]
        rest = rest[min(cut) :] if cut else ""
    atomic_write_text(page, head + DOCS_MARK + "\n" + body.rstrip("\n") + "\n" + DOCS_END + "\n\n" + rest.lstrip("\n"))


def docs_section(doc):
    md = markdown(doc).split("\n")
    # drop the document title; demote section headings one level under "## Benchmarks"
    body = [("###" + ln[2:]) if ln.startswith("## ") else ln for ln in md[2:]]
    body = [
        "![cost vs record length and operator count (log-log)](../benchmarks/results/scaling.png)"
        if ln.startswith("Scaling (log-log)")
        else ln
        for ln in body
    ]
    return "\n".join(
        [
            "## Benchmarks (`python -m benchmarks`)",
            "",
            "Regenerate with `python -m benchmarks --docs` (about 6 min on 2 cores; `--quick` for a "
            "smoke run, `--only operators` for one section). Full tables: `benchmarks/results/RESULTS.md`; "
            "what the numbers mean and why: `benchmarks/README.md`.",
            "",
        ]
        + body
    )


def main(argv=None):
    keys = [k for k, _, _ in SECTIONS]
    p = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    p.add_argument("--quick", action="store_true", help="smaller sizes, fewer repeats (smoke run)")
    p.add_argument(
        "--only",
        action="append",
        choices=keys,
        metavar="SECTION",
        help=f"run only this section (repeatable; one of {', '.join(keys)}); other sections are kept from an earlier results.json in --out",
    )
    p.add_argument("--out", default=str(HERE / "results"), help="output folder (default benchmarks/results)")
    p.add_argument("--docs", action="store_true", help="also rewrite the generated tables of docs/performance.md")
    p.add_argument(
        "--render",
        action="store_true",
        help="measure nothing: re-render RESULTS.md, scaling.png (and docs/performance.md with --docs) from --out/results.json",
    )
    args = p.parse_args(argv)

    import json

    from smafl_jax import atomic_write_json, atomic_write_text, prepare_out_dir, to_jsonable

    out = prepare_out_dir(args.out)
    if args.render:
        try:
            doc = json.loads((out / "results.json").read_text())
        except (OSError, ValueError) as exc:
            raise SystemExit(f"--render needs {out / 'results.json'} from an earlier run: {exc}") from exc
        atomic_write_text(out / "RESULTS.md", markdown(doc))
        scaling_plot(doc, out / "scaling.png")
        if args.docs:
            update_docs(doc, ROOT / "docs" / "performance.md")
        progress(f"re-rendered {out / 'RESULTS.md'} from results.json")
        return 0
    prev = {}
    if args.only and (out / "results.json").exists():
        try:
            prev = json.loads((out / "results.json").read_text()).get("sections", {})
        except (OSError, ValueError) as exc:
            progress(f"could not read earlier results.json ({exc}); writing only the sections run now")
    load0 = os.getloadavg() if hasattr(os, "getloadavg") else None
    sections = dict(prev)
    for key, mod, title in SECTIONS:
        if args.only and key not in args.only:
            continue
        sections[key] = run_section(key, mod, title, args.quick)
    m = machine()
    if load0 is not None:
        load1 = os.getloadavg()
        m["loadavg"] = f"{load0[0]:.1f} at start, {load1[0]:.1f} at end (1-min)"
    cmd = "python -m benchmarks" + (" --quick" if args.quick else "") + "".join(f" --only {k}" for k in args.only or [])
    doc = {"command": cmd, "machine": m, "sections": sections}
    atomic_write_json(out / "results.json", to_jsonable(doc))
    atomic_write_text(out / "RESULTS.md", markdown(doc))
    plotted = scaling_plot(doc, out / "scaling.png")
    if args.docs:
        update_docs(doc, ROOT / "docs" / "performance.md")
    progress(
        f"wrote {out / 'RESULTS.md'}, results.json"
        + (", scaling.png" if plotted else "")
        + (", docs/performance.md" if args.docs else "")
    )
    bad = [k for k, s in sections.items() if s["status"] == "failed"]
    return 1 if bad and len(bad) == len([s for s in sections.values() if s["status"] != "skipped"]) else 0


if __name__ == "__main__":
    sys.exit(main())
