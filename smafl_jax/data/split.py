"""Train/held-out splits: one module for fitting, diagnosis and cross-validation.

Hysteresis and thermal models carry memory, so a split never hands a model a
stretch that starts in the middle of a history it has not seen: every
`Segment` is simulated from its own first sample and a boolean ``mask`` says
which of its samples are scored.  A `Split` is a list of training segments
and a list of held-out segments.

Rules (fixed and documented, never tuned to a result):

- `time_block`: the model runs from t = 0 through the whole record; the last
  ``holdout_fraction`` (30 %) of the samples is held out.
- `branches`: for branch-labelled (FORC) records.  The distinct labels are
  sorted; the label at position i (i = 0, 1, ... in that sorted list) is held
  out when ``i % 3 == residue``; position 0 (label 0: the major loop) always
  trains.  Positions, not label values, so non-contiguous labels (0, 2, 5, 9)
  split the same way as contiguous ones (0, 1, 2, 3); with labels 0..m the rule
  is the old ``label % 3 == residue``.  Residues 0, 1, 2 give three folds.
  Each branch is one segment, simulated from its own start.
- `interleaved`: for single records where the time block would hold out a whole
  regime (the only cooling step).  The record is cut into ``n_blocks`` equal
  blocks; every m-th block is held out (m = round(1 / holdout_fraction)),
  starting at offset o, except the first block (the initial state), which
  always trains; of the m offsets the one whose held-out part the training
  part covers best (`coverage`: input level and direction) is taken, ties to
  the later offset.  The choice uses the input only, never the output.
  The model still runs through the whole record; held-out blocks are masked.
- `leave_one_record_out`: fold i holds out record i (all of it) and trains on
  the others.
- `blocked_folds`: k contiguous blocks of one record, each held out once while
  the model runs through the whole record (cross-validation of a penalty).
- `whole`: everything trains (deployed refits); branch records give one
  segment per branch.
- `make_split(record, "auto")`: branches with a branch column; else the time
  block when its coverage is at least 90 %, else `interleaved`.

`coverage` (ported from the diagnosis): the fraction of held-out samples whose
input level (within 2 % of the input span) the training part visits moving
the same way (rising, falling, holding); below 90 % the result carries a
warning that the held-out error measures extrapolation.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from smafl_jax._errors import UserInputError

from .record import Record

__all__ = [
    "Segment",
    "Split",
    "time_block",
    "branches",
    "interleaved",
    "leave_one_record_out",
    "blocked_folds",
    "whole",
    "make_split",
    "coverage",
    "branch_coverage",
    "masks",
    "load_column",
    "SPLIT_KINDS",
    "HOLDOUT_FRACTION",
    "time_cut",
    "branch_partition",
]

HOLDOUT_FRACTION = 0.3
BRANCH_COLUMN = "branch"
BRANCH_EVERY = 3
LOAD_NAMES = ("load", "force", "mass", "weight")
SPLIT_KINDS = ("auto", "time", "branch", "interleaved", "none")
COVERAGE_TOL = 0.02
COVERAGE_WARN = 0.9
MIN_TRAIN, MIN_TEST = 20, 10


@dataclasses.dataclass(frozen=True, eq=False)
class Segment:
    """A stretch simulated from its own start; scored where ``mask`` is True.

    ``index``: the record's sample indices of the stretch (to map results back);
    ``load``: the record's load column, or its sidecar load repeated, or None;
    ``extra``: the record's other columns (without the branch labels).
    """

    time: np.ndarray
    u: np.ndarray
    y: np.ndarray | None
    dt: float
    mask: np.ndarray
    load: np.ndarray | None = None
    extra: dict = dataclasses.field(default_factory=dict)
    record: str = ""
    index: np.ndarray | None = None
    label: str = ""

    def __len__(self) -> int:
        return int(self.u.shape[0])


@dataclasses.dataclass(frozen=True, eq=False)
class Split:
    """Training and held-out segments, their labels, the rule's kind and its text."""

    kind: str
    rule: str
    train: tuple[Segment, ...]
    test: tuple[Segment, ...]
    train_labels: tuple = ()
    test_labels: tuple = ()

    def n_scored(self) -> tuple[int, int]:
        """Scored samples (training, held out)."""
        return sum(int(s.mask.sum()) for s in self.train), sum(int(s.mask.sum()) for s in self.test)


def load_column(record: Record) -> str | None:
    """The first extra column whose name says load, force, mass or weight."""
    for k in record.extra:
        if any(n in k.lower() for n in LOAD_NAMES):
            return k
    return None


def _segment(record: Record, idx: np.ndarray, mask: np.ndarray | None = None, label: str = "") -> Segment:
    idx = np.asarray(idx, dtype=np.int64)
    lc = load_column(record)
    if lc is not None:
        load = np.asarray(record.extra[lc], float)[idx]
    elif record.load is not None:
        load = np.full(idx.size, float(record.load))
    else:
        load = None
    return Segment(
        time=np.asarray(record.time)[idx],
        u=np.asarray(record.u)[idx],
        y=None if record.y is None else np.asarray(record.y)[idx],
        dt=float(record.dt),
        # samples a resampling interpolated across a gap neither train nor score (`Record.measured`)
        mask=(np.ones(idx.size, bool) if mask is None else np.asarray(mask, bool)) & record.measured[idx],
        load=load,
        extra={k: np.asarray(v)[idx] for k, v in record.extra.items() if k != BRANCH_COLUMN},
        record=record.name,
        index=idx,
        label=label,
    )


def _check_fraction(holdout_fraction) -> float:
    if not (isinstance(holdout_fraction, (int, float)) and 0.0 < holdout_fraction < 1.0):
        raise UserInputError(f"holdout fraction must be in (0, 1), got {holdout_fraction!r}")
    return float(holdout_fraction)


def time_cut(n: int, holdout_fraction: float = HOLDOUT_FRACTION) -> int:
    """First held-out sample of the time block: ``round(n (1 - holdout_fraction))`` (fit, diagnose and CV alike)."""
    return round(n * (1.0 - _check_fraction(holdout_fraction)))


def time_block(record: Record, holdout_fraction: float = HOLDOUT_FRACTION) -> Split:
    """First part trains, last ``holdout_fraction`` held out; the held-out segment is the whole record, masked."""
    f = _check_fraction(holdout_fraction)
    n = len(record)
    cut = time_cut(n, f)
    if cut < MIN_TRAIN or n - cut < MIN_TEST:
        raise UserInputError(
            f"{record.name}: record too short to hold out the last {f:.0%} ({n} samples; need {MIN_TRAIN} training and "
            f"{MIN_TEST} held-out samples)"
        )
    full = np.arange(n)
    tr, te = f"0..{cut - 1}", f"{cut}..{n - 1}"
    return Split(
        "time",
        f"time block: first {1 - f:.0%} trained, last {f:.0%} held out (from t = {float(record.time[cut]):.6g} s; model run from t = 0)",
        (_segment(record, full[:cut], label=tr),),
        (_segment(record, full, mask=full >= cut, label=te),),
        (tr,),
        (te,),
    )


def _branch_groups(record: Record, column: str) -> tuple[list, dict]:
    if column not in record.extra:
        raise UserInputError(
            f"{record.name}: a branch split needs a numeric '{column}' column; the record has "
            f"{sorted(record.extra) or 'no extra columns'}"
        )
    lab = np.asarray(record.extra[column], float)
    labels = sorted(np.unique(lab).tolist())
    groups = {}
    for k in labels:
        idx = np.flatnonzero(lab == k)
        if idx.size and idx[-1] - idx[0] + 1 != idx.size:
            raise UserInputError(
                f"{record.name}: branch {_fmt(k)} is not one contiguous stretch (samples {idx[0]}..{idx[-1]} with gaps); "
                "a branch must be simulated from its own start"
            )
        groups[k] = idx
    return labels, groups


def _fmt(k) -> str:
    return str(int(k)) if float(k).is_integer() else f"{k:g}"


def branch_partition(labels, residue: int = 2) -> tuple[list, list]:
    """``(kept, held)`` branch labels: of the sorted distinct labels, positions ``i % 3 == residue`` (i != 0) are held.

    The one branch rule of fit (`smafl_jax.identify._split.split_masks`), diagnose and CV: positions, not label
    values, so non-contiguous labels split like contiguous ones.
    """
    if residue not in range(BRANCH_EVERY):
        raise UserInputError(f"residue must be 0, 1 or 2, got {residue!r}")
    labels = sorted(np.unique(np.asarray(labels, float)).tolist())
    held = [k for i, k in enumerate(labels) if i != 0 and i % BRANCH_EVERY == residue]
    return [k for k in labels if k not in held], held


def branches(record: Record, residue: int = 2, *, column: str = BRANCH_COLUMN) -> Split:
    """Interleaved branch split: sorted-label positions ``i % 3 == residue`` held out, position 0 always trained."""
    if residue not in range(BRANCH_EVERY):
        raise UserInputError(f"residue must be 0, 1 or 2, got {residue!r}")
    labels, groups = _branch_groups(record, column)
    kept, held = branch_partition(labels, residue)
    if not held:
        raise UserInputError(
            f"{record.name}: the branch split with residue {residue} holds out nothing: {len(labels)} branches "
            f"({', '.join(_fmt(k) for k in labels)}); need at least {residue + 1 if residue else 4}"
        )
    return Split(
        "branch",
        f"branches at positions i % {BRANCH_EVERY} == {residue} of the sorted labels held out (interleaved); "
        f"the first label ({_fmt(labels[0])}, the major loop) always trains",
        tuple(_segment(record, groups[k], label=f"branch {_fmt(k)}") for k in kept),
        tuple(_segment(record, groups[k], label=f"branch {_fmt(k)}") for k in held),
        tuple(_fmt(k) for k in kept),
        tuple(_fmt(k) for k in held),
    )


def _blocks(n: int, k: int) -> list[np.ndarray]:
    return [b for b in np.array_split(np.arange(n), k) if b.size]


def _masked_pair(record: Record, test: np.ndarray, kind: str, rule: str, test_label: str) -> Split:
    n = len(record)
    full = np.arange(n)
    lab_tr, lab_te = f"{record.name}: not {test_label}", f"{record.name}: {test_label}"
    return Split(
        kind,
        rule,
        (_segment(record, full, mask=~test, label=lab_tr),),
        (_segment(record, full, mask=test, label=lab_te),),
        (lab_tr,),
        (lab_te,),
    )


def interleaved(record: Record, holdout_fraction: float = HOLDOUT_FRACTION, *, n_blocks: int = 10) -> Split:
    """Every m-th of ``n_blocks`` equal blocks held out, at the offset the training part covers best (module docstring)."""
    f = _check_fraction(holdout_fraction)
    n = len(record)
    if not isinstance(n_blocks, int) or n_blocks < 2:
        raise UserInputError(f"n_blocks must be an integer >= 2, got {n_blocks!r}")
    every = max(2, round(1.0 / f))
    blocks = _blocks(n, n_blocks)
    if len(blocks) < every:
        raise UserInputError(f"{record.name}: {n} samples are too few for {n_blocks} blocks")
    best = None
    for off in range(every):
        test = np.zeros(n, bool)
        chosen = [j for j in range(off, len(blocks), every) if j != 0]  # the first block (initial state) always trains
        for j in chosen:
            test[blocks[j]] = True
        if test.sum() < MIN_TEST or (~test).sum() < MIN_TRAIN:
            continue
        label = "blocks " + ",".join(str(j) for j in chosen)
        rule = (
            f"interleaved blocks: {len(blocks)} equal blocks, one in every {every} held out from block {off} "
            f"({test.mean():.0%} of the samples), the offset whose held-out part the training part covers best; "
            "model run through the whole record"
        )
        sp = _masked_pair(record, test, "interleaved", rule, label)
        cov = coverage(sp)["covered_fraction"]
        if best is None or cov >= best[0]:
            best = (cov, sp)
    if best is None:
        raise UserInputError(f"{record.name}: record too short for an interleaved split ({n} samples)")
    return best[1]


def _record_segments(record: Record) -> tuple[list[Segment], list[str]]:
    if BRANCH_COLUMN in record.extra:
        labels, groups = _branch_groups(record, BRANCH_COLUMN)
        return [_segment(record, groups[k], label=f"{record.name}: branch {_fmt(k)}") for k in labels], [
            f"{record.name}: branch {_fmt(k)}" for k in labels
        ]
    return [_segment(record, np.arange(len(record)), label=record.name)], [record.name]


def _as_list(records) -> list[Record]:
    if isinstance(records, Record):
        return [records]
    records = list(records)
    if not records or not all(isinstance(r, Record) for r in records):
        raise UserInputError("expected one or more Record objects")
    return records


def leave_one_record_out(records) -> list[Split]:
    """Fold i: record i held out whole, the others train (branch records as one segment per branch)."""
    records = _as_list(records)
    if len(records) < 2:
        raise UserInputError(f"leave-one-record-out needs at least 2 records, got {len(records)}")
    names = [r.name for r in records]
    if len(set(names)) != len(names):
        raise UserInputError(f"record names must differ for leave-one-record-out, got {names}")
    per = [_record_segments(r) for r in records]
    folds = []
    for i, r in enumerate(records):
        tr = [s for j, (segs, _) in enumerate(per) if j != i for s in segs]
        trl = [lab for j, (_, labs) in enumerate(per) if j != i for lab in labs]
        folds.append(
            Split(
                "record",
                f"leave one record out: {r.name} held out, the other {len(records) - 1} records train",
                tuple(tr),
                tuple(per[i][0]),
                tuple(trl),
                tuple(per[i][1]),
            )
        )
    return folds


def blocked_folds(record: Record, k: int = 5) -> list[Split]:
    """k contiguous blocks, each held out once; the model runs through the whole record in every fold."""
    if not isinstance(k, int) or k < 2:
        raise UserInputError(f"k must be an integer >= 2, got {k!r}")
    n = len(record)
    if n < k * MIN_TEST:
        raise UserInputError(f"{record.name}: {n} samples are too few for {k} blocks of at least {MIN_TEST}")
    folds = []
    for j, b in enumerate(_blocks(n, k)):
        test = np.zeros(n, bool)
        test[b] = True
        folds.append(
            _masked_pair(
                record,
                test,
                "blocked",
                f"blocked {k}-fold: block {j} (samples {b[0]}..{b[-1]}) held out; model run through the whole record",
                f"block {j}",
            )
        )
    return folds


def whole(records) -> Split:
    """Everything trains (no held-out part); branch records give one segment per branch."""
    segs, labels = [], []
    for r in _as_list(records):
        s, lab = _record_segments(r)
        segs += s
        labels += lab
    return Split("all", "every sample trains (no held-out part)", tuple(segs), (), tuple(labels), ())


def make_split(record: Record, kind: str = "auto", *, holdout_fraction: float = HOLDOUT_FRACTION, residue: int = 2) -> Split:
    """Split one record by name: ``"time"``, ``"branch"``, ``"interleaved"``, ``"none"`` or ``"auto"`` (module docstring)."""
    if kind not in SPLIT_KINDS:
        raise UserInputError(f"unknown split {kind!r}; choose one of {SPLIT_KINDS}")
    if kind == "auto":
        if BRANCH_COLUMN in record.extra:
            return branches(record, residue)
        sp = time_block(record, holdout_fraction)
        if coverage(sp)["covered_fraction"] >= COVERAGE_WARN:
            return sp
        return interleaved(record, holdout_fraction)
    if kind == "time":
        return time_block(record, holdout_fraction)
    if kind == "branch":
        return branches(record, residue)
    if kind == "interleaved":
        return interleaved(record, holdout_fraction)
    return whole(record)


def masks(split: Split, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Boolean (train, held-out) masks over the samples of the one record a split was made from."""
    recs = {s.record for s in split.train + split.test}
    if len(recs) != 1:
        raise UserInputError(f"masks need a split of one record, this one spans {sorted(recs)}")
    n = n if n is not None else 1 + max(int(s.index.max()) for s in split.train + split.test)
    out = []
    for segs in (split.train, split.test):
        m = np.zeros(n, bool)
        for s in segs:
            m[s.index[s.mask]] = True
        out.append(m)
    return out[0], out[1]


def _directions(u: np.ndarray, span: float, window: int = 5, threshold: float = 0.002) -> np.ndarray:
    """Per sample: +1 rising, -1 falling, 0 holding (slope of a short moving average vs ``threshold`` x span per sample)."""
    u = np.asarray(u, float)
    if u.size < 2:
        return np.zeros(u.size, int)
    w = min(window, u.size)
    # edge padding (the diagnosis used zero padding, which turned the last samples of a rising ramp into "falling")
    smooth = np.convolve(np.pad(u, (w // 2, w - 1 - w // 2), mode="edge"), np.ones(w) / w, mode="valid")
    d = np.gradient(smooth)
    return np.where(d > threshold * span, 1, np.where(d < -threshold * span, -1, 0))


def coverage(split: Split, tol: float = COVERAGE_TOL, warn_below: float = COVERAGE_WARN) -> dict:
    """How much of the held-out part the training part has seen: input level AND direction (rising/falling/holding).

    A held-out sample counts as covered when the training part visits an input
    within ``tol`` x the input span while moving the same way.  Hysteresis
    branches are direction-specific, so a held-out block on a branch never
    trained (e.g. the cooling step of a single heat-hold-cool record) measures
    extrapolation, not prediction; the result says so (``warning``) when the
    covered fraction is below ``warn_below``.
    """
    segs = split.train + split.test
    span = float(np.ptp(np.concatenate([np.asarray(s.u, float) for s in segs]))) if segs else 0.0
    span = span or 1.0
    names = {-1: "falling", 0: "holding", 1: "rising"}
    seen = {k: [] for k in names}
    for s in split.train:
        d = _directions(s.u, span)
        for k in names:
            seen[k].append(np.asarray(s.u, float)[(d == k) & s.mask])
    levels = {k: np.sort(np.concatenate(v)) if v else np.zeros(0) for k, v in seen.items()}
    counts = {name: [0, 0] for name in names.values()}
    for s in split.test:
        d = _directions(s.u, span)[s.mask]
        x = np.asarray(s.u, float)[s.mask]
        for k, name in names.items():
            xs, lv = x[d == k], levels[k]
            if xs.size == 0:
                continue
            if lv.size:
                i = np.searchsorted(lv, xs)
                near = np.minimum(np.abs(lv[np.clip(i - 1, 0, lv.size - 1)] - xs), np.abs(lv[np.clip(i, 0, lv.size - 1)] - xs))
                counts[name][0] += int(np.sum(near <= tol * span))
            counts[name][1] += int(xs.size)
    total = sum(c[1] for c in counts.values())
    frac = sum(c[0] for c in counts.values()) / total if total else 1.0
    out = {
        "covered_fraction": float(frac),
        "tolerance_of_span": tol,
        "by_direction": {n: {"heldout_samples": c[1], "covered": (c[0] / c[1] if c[1] else None)} for n, c in counts.items()},
    }
    if frac < warn_below:
        worst = min((n for n in counts if counts[n][1]), key=lambda n: counts[n][0] / counts[n][1])
        out["warning"] = (
            f"only {100 * frac:.0f} % of the held-out samples lie on input levels the training part visits in the same "
            f"direction ({worst} samples least: {100 * counts[worst][0] / counts[worst][1]:.0f} %); the held-out errors "
            "measure extrapolation to an untrained branch, not prediction"
        )
    return out


def branch_directions(x: np.ndarray, deadband: float) -> np.ndarray:
    """Per sample: +1 on a rising branch, -1 on a falling one, 0 before the first move: the direction of the last move
    larger than ``deadband`` (a play operator of that half-width), whatever its rate.

    Why not `_directions` (the sign of a short slope): a slow signal such as a thermal state moves less than its
    threshold per sample and reads "holding" on both the heating and the cooling branch; a PWM ripple on it flips
    the slope's sign every period although the state stays on one branch.
    """
    from ..ops import play

    x = np.asarray(x, float)
    if x.size == 0:
        return np.zeros(0, int)
    # the play operator of half-width `deadband` started at x[0]: it moves only when x leaves its band, and the sign
    # of its last move is the branch (0 before it first moves)
    p = np.asarray(play(x, np.asarray([float(deadband)]), y0=np.asarray([x[0]]), method="scan"))[:, 0]
    step = np.sign(np.diff(p, prepend=p[0])).astype(int)
    return step[np.maximum.accumulate(np.where(step != 0, np.arange(x.size), 0))]


def branch_coverage(
    x: np.ndarray,
    train: np.ndarray,
    test: np.ndarray,
    *,
    tol: float = COVERAGE_TOL,
    warn_below: float = COVERAGE_WARN,
    what: str = "input",
) -> dict:
    """`coverage` for one simulation ``x`` (e.g. the fitted model's hysteresis input) scored through boolean masks, with
    the branch direction of `branch_directions` (deadband ``tol`` x the span of ``x``).

    A held-out sample counts as covered when the training samples visit a value within ``tol`` x span on the same
    branch (samples before the first move match either branch).  Measured why: an independent PWM record whose
    thermal state rose through the whole training block and fell through the held-out block had 100 % coverage on
    the drive voltage (it switches up and down every period) and 14x the noise on held-out data; on the thermal
    state its coverage is low and the warning says the held-out error measures an untrained branch.
    """
    x = np.asarray(x, float)
    train, test = np.asarray(train, bool), np.asarray(test, bool)
    if x.shape != train.shape or x.shape != test.shape:
        raise UserInputError(f"branch_coverage: x {x.shape}, train {train.shape} and test {test.shape} must have one shape")
    span = float(np.ptp(x[train | test])) if (train | test).any() else 0.0
    span = span or 1.0
    d = branch_directions(x, tol * span)
    names = {-1: "falling", 1: "rising", 0: "before the first move"}
    counts = {}
    for k, name in names.items():
        xs = x[test & (d == k)]
        if xs.size == 0:
            continue
        same = ((d == k) | (d == 0)) if k else np.ones(x.size, bool)
        lv = np.sort(x[train & same])
        near = np.full(xs.size, np.inf)
        if lv.size:
            i = np.searchsorted(lv, xs)
            near = np.minimum(np.abs(lv[np.clip(i - 1, 0, lv.size - 1)] - xs), np.abs(lv[np.clip(i, 0, lv.size - 1)] - xs))
        counts[name] = [int(np.sum(near <= tol * span)), int(xs.size)]
    total = sum(c[1] for c in counts.values())
    frac = sum(c[0] for c in counts.values()) / total if total else 1.0
    out = {
        "covered_fraction": float(frac),
        "signal": what,
        "tolerance_of_span": tol,
        "by_direction": {n: {"heldout_samples": c[1], "covered": c[0] / c[1]} for n, c in counts.items()},
    }
    if frac < warn_below:
        worst = min(counts, key=lambda n: counts[n][0] / counts[n][1])
        out["warning"] = (
            f"only {100 * frac:.0f} % of the held-out samples lie on values of the {what} that the training part visits "
            f"on the same branch ({worst} samples least: {100 * counts[worst][0] / counts[worst][1]:.0f} %); the "
            "held-out errors measure extrapolation to an untrained branch, not prediction"
        )
    return out
