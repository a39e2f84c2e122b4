"""Diagnosis of several records of one rig (``smafl diagnose A.csv B.csv ...``): each record on its own, then agreement.

Why per record: a missing physical effect of the rig (a resistance that rises with temperature, creep, a sensor lag)
is in every run, while the misfit a flexible effect soaks up on one record (its drive, its start, a fault) is not.
Each record goes through the whole single-record diagnosis (its own split, screened base with its own start, calibrated
selection against its own null records), and an effect is named for the set only when it is selected on more than half
of the records (on both of two).  What this is not: one joint model of all records with one start per record (as
``smafl fit A.csv B.csv`` fits); the extended models are fitted per record, in ``OUT/<record>/``.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any, NamedTuple

from .._blas import blas_limited
from .._errors import UserInputError

__all__ = ["RecordsDiagnosis", "diagnose_records", "agreement", "AGREEMENT_RULE"]

LOGGER = logging.getLogger(__name__)

AGREEMENT_RULE = (
    "each record diagnosed on its own (its own split, base fit, start and calibrated selection); an effect is named for "
    "the set when it is selected on more than half of the records (on both of two); effects selected on fewer are listed "
    "as seen on some records only"
)


class RecordsDiagnosis(NamedTuple):
    """What `diagnose_records` produced: ``report`` (the set's diagnosis.json), the per-record `Diagnosis` objects and
    the folders their outputs went to."""

    report: dict
    diagnoses: list
    folders: list


def agreement(selected: list[list[str]]) -> dict[str, Any]:
    """``{"effects": {name: records it was selected on (indices)}, "consistent": [...], "some_records": [...]}`` from each
    record's selected effects (`AGREEMENT_RULE`: consistent when selected on more than half of the records)."""
    n = len(selected)
    if n < 1:
        raise UserInputError("agreement needs at least one record's selection")
    effects: dict[str, list[int]] = {}
    for i, names in enumerate(selected):
        for name in names:
            effects.setdefault(name, []).append(i)
    need = n // 2 + 1
    return {
        "effects": effects,
        "needed": need,
        "consistent": sorted(k for k, v in effects.items() if len(v) >= need),
        "some_records": sorted(k for k, v in effects.items() if len(v) < need),
    }


def _folders(records) -> list[str]:
    """One sub-folder name per record: its file stem, numbered when two records share one."""
    stems = [Path(r.path).stem if r.path else r.name for r in records]
    return [s if stems.count(s) == 1 else f"{s}_{i + 1}" for i, s in enumerate(stems)]


def _row(rec, folder, diag) -> dict[str, Any]:
    noise = diag.report.get("noise") or {}
    return {
        "file": Path(rec.path).name if rec.path else rec.name,
        "folder": folder,
        "n_samples": len(rec),
        "selected": list(diag.selected),
        "ambiguous": list(diag.ambiguous),
        "unspecific": list(diag.unspecific),
        "heldout_rmse_before": diag.heldout_rmse_before,
        "heldout_rmse_after": diag.heldout_rmse_after,
        "heldout_e_r_before": diag.heldout_e_r_before,
        "heldout_e_r_after": diag.heldout_e_r_after,
        "base_heldout_over_noise": noise.get("base_heldout_ratio"),
        "extended_heldout_over_noise": noise.get("extended_heldout_ratio"),
        "unexplained": (diag.unexplained or {}).get("verdict"),
        "warnings": list(diag.warnings),
    }


@blas_limited
def diagnose_records(records, out, **kwargs) -> RecordsDiagnosis:
    """Diagnose each of ``records`` (`Record`s of one rig, same columns) with `diagnose` (``kwargs`` are its settings),
    write each record's outputs to ``out/<record stem>/`` and the set's ``diagnosis.json`` and ``report.md`` to ``out``.

    The set's answer follows `AGREEMENT_RULE`.  ``out`` must be prepared by the caller (`prepare_out_dir`)."""
    from .._io import atomic_write_json, atomic_write_text, prepare_out_dir
    from .._progress import say, tagged
    from ..report._report import write_diagnosis
    from ._diagnose import check_record, diagnose

    records = list(records)
    if len(records) < 2:
        raise UserInputError(f"diagnose_records needs at least two records, got {len(records)}; use diagnose for one")
    for rec in records:
        check_record(rec)  # every record, before any work
    out = Path(out)
    folders = _folders(records)
    verbose = bool(kwargs.get("verbose", False))
    diagnoses, rows = [], []
    for i, (rec, folder) in enumerate(zip(records, folders)):
        say(f"record {i + 1} of {len(records)}: {rec.name}", verbose)
        with tagged(folder):
            diag = diagnose(rec, **kwargs)
        sub = prepare_out_dir(out / folder)
        write_diagnosis(sub, rec, diag)
        diagnoses.append(diag)
        rows.append(_row(rec, folder, diag))
    agree = agreement([r["selected"] for r in rows])
    ratios = [r["heldout_rmse_after"] / r["heldout_rmse_before"] for r in rows if r["heldout_rmse_before"]]
    report = {
        "kind": "several_records",
        "rule": AGREEMENT_RULE,
        "n_records": len(records),
        "records": rows,
        "effects": {k: {"selected_on": [rows[i]["file"] for i in v], "count": len(v)} for k, v in agree["effects"].items()},
        "consistent": agree["consistent"],
        "some_records": agree["some_records"],
        "needed": agree["needed"],
        # geometric mean over records of held-out RMSE after / before each record's own selection
        "heldout_rmse_ratio_geomean": math.exp(sum(math.log(x) for x in ratios) / len(ratios)) if ratios else None,
        "not_done": "one joint model over the records (one start per record, as smafl fit A.csv B.csv fits): each record's "
        "extended model is fitted on that record alone",
    }
    atomic_write_json(out / "diagnosis.json", report)
    atomic_write_text(out / "report.md", _markdown(report))
    return RecordsDiagnosis(report=report, diagnoses=diagnoses, folders=[out / f for f in folders])


def _markdown(report) -> str:
    fmt = lambda x, p=4: "-" if x is None else f"{x:.{p}g}"
    lines = [
        f"# Diagnosis of {report['n_records']} records",
        "",
        f"Rule: {report['rule']}.",
        "",
        f"**Named for the set**: {', '.join(report['consistent']) or 'none'}"
        + (f"; seen on some records only: {', '.join(report['some_records'])}" if report["some_records"] else ""),
        "",
        "| record | selected | held-out RMSE before -> after | x noise before -> after | unexplained | folder |",
        "|---|---|---|---|---|---|",
    ]
    for r in report["records"]:
        sel = ", ".join(r["selected"]) or "none"
        if r["ambiguous"]:
            sel += f" (ambiguous with {', '.join(n for n in r['ambiguous'] if n not in r['selected'])})"
        lines.append(
            f"| {r['file']} | {sel} | {fmt(r['heldout_rmse_before'])} -> {fmt(r['heldout_rmse_after'])} | "
            f"{fmt(r['base_heldout_over_noise'], 3)} -> {fmt(r['extended_heldout_over_noise'], 3)} | "
            f"{r['unexplained'] or '-'} | [{r['folder']}/report.md]({r['folder']}/report.md) |"
        )
    lines += ["", f"Not done: {report['not_done']}.", ""]
    return "\n".join(lines)
