"""``smafl check DATA.csv [more files / folder / glob] [--input COL] [--output COL] [--resample DT] [--json OUT.json]``.

Reads the records (irregular time stamps are kept and reported unless
``--resample`` is given), runs the data checks of `smafl_jax.data.checks` on
each record and across the set, and prints one line per finding: record,
kind, column, time span, samples, size and the suggested action.  Exit code 0
when the check ran (with or without findings), 2 when a file cannot be read.
Imports only the numpy-based data package, so it starts fast.
"""

from __future__ import annotations

import sys
from collections import Counter, defaultdict
from pathlib import Path

#: Findings of one kind in one column of one record printed in full; the rest are counted.
MAX_LINES_PER_GROUP = 5
#: The --time option's help, shared by every command that reads records.
TIME_HELP = (
    'time column (default: the sidecar\'s "time", else time_s, else the one column named like time, t or timestamp); '
    "a unit ms or us in its name ('time [ms]', 't_ms') or in the sidecar's units is converted to seconds"
)

WINDOW_HELP = (
    "keep only the samples with START <= time <= END (seconds on the record's time axis; either may be empty: "
    "'8.07:' cuts a faulty start, ':120' a faulty end); every record of the run, said in the outputs"
)


def add_window_argument(p):
    """``--window START:END``: how a user acts on a data-check finding without editing the file."""
    p.add_argument("--window", default=None, metavar="START:END", help=WINDOW_HELP)


#: ``--resample``'s help, one text for every command that loads records.
RESAMPLE_HELP = (
    "put irregular time stamps on a uniform DT-second grid by linear interpolation ('auto' = median step); every bridged "
    "gap is reported, and the samples interpolated across a gap get no weight in fits and leave every score. Without it "
    "irregular sampling is an error"
)


def add_resample_argument(p):
    """``--resample DT|auto`` (parse with `smafl_jax.data._data.parse_resample`)."""
    p.add_argument("--resample", default=None, metavar="DT|auto", help=RESAMPLE_HELP)


def apply_window(records, text):
    """``records`` cut to the ``--window`` (unchanged without one); the cut is in each record's ``processing``."""
    from smafl_jax.data._data import parse_window

    w = parse_window(text)
    return records if w is None else [r.window(*w) for r in records]


def add_parser(sub):
    p = sub.add_parser("check", help="check measured records for faults (offset jumps, spikes, flat runs, gaps, odd runs)")
    p.add_argument("data", nargs="+", help="CSV files, folders (their *.csv) or glob patterns; one column choice for all")
    p.add_argument("--input", default=None, help="input column (default: the sidecar's, else a common name)")
    p.add_argument("--output", default=None, help="output column (default: the sidecar's, else a common name)")
    p.add_argument("--time", default=None, metavar="COL", help=TIME_HELP)
    add_resample_argument(p)
    add_window_argument(p)
    p.add_argument("--json", default=None, metavar="OUT.json", help="also write the records and findings to this JSON file")
    p.set_defaults(func=run)
    return p


def _resample_arg(text):
    from smafl_jax._errors import UserInputError

    if text is None or text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        raise UserInputError(f"--resample needs a sample time in seconds or 'auto', got {text!r}") from None


def _atomic_write_json(path, obj):
    from smafl_jax._io import atomic_write_json  # numpy-only module: keeps `smafl check` fast

    atomic_write_json(path, obj)


def run(args):
    from smafl_jax.data import check_records, load_records

    resample = _resample_arg(args.resample)
    kw = {"time": args.time}
    kw.update({"resample": resample} if resample is not None else {"irregular": "keep"})
    records = apply_window(load_records(args.data, args.input, args.output, **kw), args.window)
    findings = check_records(records)
    for r in records:
        unit = {c: f" {u}" for c, u in r.units.items()}
        print(
            f"{r.name}: {len(r)} samples, dt {r.dt:.6g} s, input '{r.input_name}'{unit.get(r.input_name, '')}, "
            f"output '{r.output_name}'{unit.get(r.output_name, '')}"
            + (f", load {r.load:g}{unit.get('load', '')}" if r.load is not None else "")
        )
        for note in r.processing:
            print(f"  read: {note}")
    by_name = {r.name: r for r in records}
    groups = defaultdict(list)
    for f in findings:
        groups[(f.record, f.kind, f.column)].append(f)
    print()
    for (name, kind, column), fs in groups.items():
        rec = by_name.get(name)
        unit = "s" if column == "time_s" else (rec.units.get(column, "") if rec is not None else "")
        for f in fs[:MAX_LINES_PER_GROUP]:
            print(f.line(unit))
        if len(fs) > MAX_LINES_PER_GROUP:
            print(f"{name}  {kind}  [{column}]  ... and {len(fs) - MAX_LINES_PER_GROUP} more (all in --json)")
    counts = Counter(f.kind for f in findings)
    if findings:
        summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
        print(f"\n{len(findings)} finding{'s' if len(findings) > 1 else ''} in {len(records)} record(s): {summary}")
    else:
        print(f"no findings in {len(records)} record(s)")
    if args.json:
        out = Path(args.json)
        if out.exists():
            print(f"note: replacing existing {out}", file=sys.stderr)
        doc = {
            "records": [
                {
                    "name": r.name,
                    "path": r.path,
                    "sha256": r.sha256,
                    "n_samples": len(r),
                    "dt_s": r.dt,
                    "input": r.input_name,
                    "output": r.output_name,
                    "load": r.load,
                    "processing": list(r.processing),
                }
                for r in records
            ],
            "findings": [f.to_dict() for f in findings],
            "counts": dict(counts),
        }
        _atomic_write_json(out, doc)
        print(f"wrote {out}")
    return 0
