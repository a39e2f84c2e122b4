"""Saving and loading models as JSON, and atomic writing of results.

Models are written as human-readable JSON (never pickle):
``{"type": "Cascade", "thermal": {"type": "JouleThermal", "k1": 0.05, ...}, ...}``.
A model file is ``{"format": "smafl-model", "version": 1, "model": {...}}``;
``fit.json`` files carry the same ``"model"`` entry among their metrics, so
every command that takes a model accepts either.  Other modules make their
model classes loadable with `register_model`.

All writers go to a temporary file in the target folder and `os.replace` it,
so an interrupted run never leaves a half-written result behind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import logging
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ._errors import UserInputError

__all__ = [
    "register_model",
    "model_to_dict",
    "model_from_dict",
    "save_model",
    "load_model",
    "load_model_file",
    "atomic_write_text",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_savefig",
    "atomic_write_csv",
    "prepare_out_dir",
    "check_writable_file",
    "remove_created_dirs_if_empty",
    "to_jsonable",
    "read_json_file",
]

FORMAT = "smafl-model"
VERSION = 1
_REGISTRY: dict[str, type] = {}


_Class = TypeVar("_Class", bound=type)


def register_model(cls: _Class) -> _Class:
    """Class decorator: make an `equinox.Module` model loadable from JSON by its class name."""
    _REGISTRY[cls.__name__] = cls
    return cls


def _is_jax_array(x):
    jax = sys.modules.get("jax")  # no JAX array can exist before JAX is imported; keeps this module light
    return jax is not None and isinstance(x, jax.Array)


def to_jsonable(x: Any) -> Any:
    """Arrays -> nested lists, numpy scalars -> Python, NaN/inf -> None (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, (np.ndarray, np.generic)) or _is_jax_array(x):
        return to_jsonable(np.asarray(x).tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _registered(name):
    """The model class registered as ``name``; imports the package's model modules first if needed."""
    if name not in _REGISTRY:
        from . import _load_all  # the package imports its modules lazily; registration happens on import

        _load_all()
    if name not in _REGISTRY:  # a hysteresis model registered in _choices.HYSTERESIS but not (yet) a public export
        from .models._hysteresis import hysteresis_models

        hysteresis_models()
    return _REGISTRY.get(name)


def model_to_dict(model: Any) -> dict[str, Any]:
    """Named-field dict of a registered model (recursive)."""
    import equinox as eqx

    if _registered(type(model).__name__) is None:
        raise UserInputError(f"model type {type(model).__name__} is not registered for saving")
    out = {"type": type(model).__name__}
    for f in dataclasses.fields(model):
        val = getattr(model, f.name)
        if f.metadata.get("transient"):
            if val is not None:  # a compile form (`Cascade.compile_form`) is never saved
                raise UserInputError(f"{type(model).__name__}.{f.name}: save the model's user form, not its compile form")
            continue
        if isinstance(val, eqx.Module):
            out[f.name] = model_to_dict(val)
        elif isinstance(val, (tuple, list)) and val and all(isinstance(v, eqx.Module) for v in val):
            out[f.name] = [model_to_dict(v) for v in val]
        elif hasattr(val, "shape") and np.size(val) == 0 and np.ndim(val) > 1:
            # an empty (0, k) array would come back from JSON as shape (0,): keep its shape
            out[f.name] = {"shape": list(np.shape(val)), "values": []}
        elif f.metadata.get("constraint") == "positive" and hasattr(val, "shape"):
            out[f.name] = to_jsonable(_roundoff_to_zero(np.asarray(val, dtype=np.float64)))
        else:
            out[f.name] = to_jsonable(val)
    return out


#: A value of a ``>= 0`` field at most this far below 0 (relative to the field's largest magnitude) is round-off of a
#: fit that ended on the bound (a diagnosis' base wrote -4.4e-19 among gains of order 1, and then neither
#: ``smafl simulate`` nor ``smafl sample`` would read its own file): saved and read as 0.
ROUNDOFF_RTOL = 1e-9
#: ... or at most this far below 0 whatever the field's scale (all other gains 0: nothing to be relative to).
ROUNDOFF_ATOL = 1e-12


def _roundoff_to_zero(arr: np.ndarray) -> np.ndarray:
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        return arr
    tol = max(ROUNDOFF_RTOL * float(np.max(np.abs(arr))), ROUNDOFF_ATOL)
    return np.where((arr < 0) & (arr >= -tol), 0.0, arr)


#: Positive fields that must be strictly > 0 (rates, tilts, spans and time constants divide or scale by
#: them); other positive fields (gains) may be exactly 0, which a non-negative least-squares fit produces.
_NONZERO_FIELDS = frozenset({"k1", "k2", "alpha", "u_span", "tau"})


def _check_positive_field(f, arr, where):
    """A field declared `positive()` must hold no negative value (and no zero where zero is undefined)."""
    if f.metadata.get("constraint") != "positive":
        return
    bad = arr < 0 if f.name not in _NONZERO_FIELDS else arr <= 0
    if np.any(bad):
        value = float(np.ravel(arr)[np.flatnonzero(np.ravel(bad))[0]])
        need = "> 0" if f.name in _NONZERO_FIELDS else ">= 0"
        raise UserInputError(f"{where}: must be {need}, got {value:g}")


def model_from_dict(d: Any, *, where: str = "model") -> Any:
    """Inverse of `model_to_dict`; errors name the offending entry."""
    import jax.numpy as jnp

    if not isinstance(d, dict) or "type" not in d:
        raise UserInputError(f"{where}: expected an object with a 'type' entry")
    name = d["type"]
    cls = _registered(name)
    if cls is None:
        raise UserInputError(f"{where}: unknown model type {name!r}; known: {sorted(_REGISTRY)}")
    kwargs = {}
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key, val in d.items():
        if key == "type":
            continue
        if key not in fields:
            raise UserInputError(f"{where}: {name} has no field {key!r}; fields are {sorted(fields)}")
        f = fields[key]
        if isinstance(val, dict) and "type" in val:
            kwargs[key] = model_from_dict(val, where=f"{where}.{key}")
        elif isinstance(val, list) and val and all(isinstance(v, dict) and "type" in v for v in val):
            kwargs[key] = tuple(model_from_dict(v, where=f"{where}.{key}[{i}]") for i, v in enumerate(val))
        elif f.metadata.get("static", False):
            kwargs[key] = tuple(val) if isinstance(val, list) else val
        else:
            if val is None:
                kwargs[key] = None
                continue
            if isinstance(val, dict) and set(val) == {"shape", "values"} and not val["values"]:
                val = np.zeros(tuple(int(n) for n in val["shape"]))
            arr = np.asarray(val, dtype=np.float64)
            if not np.all(np.isfinite(arr)):
                raise UserInputError(f"{where}.{key}: non-finite value in saved parameters")
            if f.metadata.get("constraint") == "positive" and f.name not in _NONZERO_FIELDS:
                arr = _roundoff_to_zero(arr)
            _check_positive_field(f, arr, f"{where}.{key}")
            kwargs[key] = jnp.asarray(arr)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        raise UserInputError(f"{where}: cannot build {name}: {exc}") from None


def save_model(path: str | os.PathLike, model: Any, **extra: Any) -> None:
    """Write ``model`` (and any JSON-able ``extra`` entries) to ``path`` atomically."""
    doc = {"format": FORMAT, "version": VERSION, "model": model_to_dict(model)}
    doc.update(to_jsonable(extra))
    atomic_write_json(path, doc)


def read_json_file(path, what="file"):
    """Parsed JSON object from ``path``; `UserInputError` naming the file when missing or malformed."""
    path = Path(path)
    if not path.exists():
        raise UserInputError(f"{path}: {what} not found")
    try:
        doc = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserInputError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise UserInputError(f"{path}: expected a JSON object")
    return doc


def load_model_file(path: str | os.PathLike) -> tuple[Any, dict[str, Any]]:
    """``(model, document)`` from a model file or a ``fit.json``."""
    doc = read_json_file(path)
    if "model" not in doc:
        raise UserInputError(f"{path}: no 'model' entry; expected a model file or a fit.json")
    return model_from_dict(doc["model"], where=f"{path}: model"), doc


def load_model(path: str | os.PathLike) -> Any:
    """The model stored in a model file or ``fit.json``."""
    return load_model_file(path)[0]


# -- atomic output -------------------------------------------------------------


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _os_message(exc: OSError) -> str:
    """``strerror`` of an OSError without its errno prefix (the path is named by the caller)."""
    return exc.strerror or str(exc)


#: Folders `prepare_out_dir` created in this process, so that a failed run can remove them when empty.
_CREATED_DIRS: list[Path] = []


def _mkdir(folder: Path, what="output folder"):
    """``mkdir -p`` that records the folders it created and turns OSError into a UserInputError naming the path."""
    folder = Path(folder)
    missing = []
    p = folder
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    if p.exists() and not p.is_dir():
        raise UserInputError(f"cannot create {what} {folder}: {p} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"cannot create {what} {folder}: {_os_message(exc)}") from None
    created = list(reversed(missing))
    _CREATED_DIRS.extend(created)
    return created


def remove_created_dirs_if_empty():
    """Remove the folders this process created that are still empty (after a failed run); innermost first."""
    removed = []
    while _CREATED_DIRS:
        d = _CREATED_DIRS.pop()
        try:
            d.rmdir()  # only succeeds when empty
            removed.append(d)
        except OSError:
            pass
    return removed


#: Temporary files of atomic writes in progress (removed by `remove_temporary_files` when a run is interrupted).
_IN_FLIGHT: set[str] = set()


def remove_temporary_files():
    """Remove the temporary files of atomic writes still in progress (an interrupt ending the process)."""
    for tmp in list(_IN_FLIGHT):
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        _IN_FLIGHT.discard(tmp)


def atomic_write_bytes(path, data: bytes):
    """Write ``data`` to ``path`` through a temporary file in the same folder and `os.replace`.

    Failures (read-only or special file systems, a folder where a file is
    expected, a full disk) raise `UserInputError` naming ``path``.
    """
    path = Path(path)
    if path.is_dir():
        raise UserInputError(f"cannot write {path}: it is a folder, expected a file name")
    if not path.parent.is_dir():
        _mkdir(path.parent, "folder")
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise UserInputError(f"cannot write {path}: {_os_message(exc)}") from None
    _IN_FLIGHT.add(tmp)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give results normal permissions
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise UserInputError(f"cannot write {path}: {_os_message(exc)}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    finally:
        _IN_FLIGHT.discard(tmp)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike, obj: Any) -> None:
    atomic_write_text(path, json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")


def atomic_savefig(fig: Any, path: str | os.PathLike, **kwargs: Any) -> None:
    """Save a matplotlib figure atomically (format from the file suffix)."""
    path = Path(path)
    buf = io.BytesIO()
    kwargs.setdefault("dpi", 120)
    kwargs.setdefault("bbox_inches", "tight")
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", **kwargs)
    atomic_write_bytes(path, buf.getvalue())


def atomic_write_csv(path: str | os.PathLike, columns: dict, *, fmt: str = "%.10g") -> None:
    """Write named equal-length 1-D columns as a CSV with a header."""
    names = list(columns)
    arrs = [np.asarray(columns[n], dtype=np.float64) for n in names]
    lengths = {a.shape for a in arrs}
    if len(lengths) != 1:
        raise ValueError(f"columns differ in length: { {n: a.shape for n, a in zip(names, arrs)} }")
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack(arrs), delimiter=",", header=",".join(names), comments="", fmt=fmt)
    atomic_write_text(path, buf.getvalue())


def check_writable_file(path, what="output file"):
    """Fail early (before any work) when ``path`` cannot be written: a folder, or in a folder that cannot be written."""
    path = Path(path)
    if path.is_dir():
        raise UserInputError(f"{what} {path} is a folder; give a file name")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise UserInputError(f"cannot write {what} {path}: {parent} is a file, not a folder")
    try:  # a probe file in the nearest existing folder: catches read-only and special file systems
        fd, probe = tempfile.mkstemp(dir=parent, prefix=".smafl-write-probe.")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise UserInputError(f"cannot write {what} {path}: {_os_message(exc)}") from None
    return path


def prepare_out_dir(out: str | os.PathLike, *, announce: bool = True) -> Path:
    """Create the output folder; say so when it already holds results that will be replaced.

    Checks that the folder can be written to (a probe file is created and removed),
    so a read-only or special file system fails here, before any work is done,
    with a `UserInputError` naming the folder.  Folders created here are
    remembered: `remove_created_dirs_if_empty` removes them after a failed run.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserInputError(f"{out}: exists and is not a folder")
    try:
        existing = sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) if out.exists() else []
    except OSError as exc:
        raise UserInputError(f"cannot read output folder {out}: {_os_message(exc)}") from None
    created = _mkdir(out)
    try:
        fd, probe = tempfile.mkstemp(dir=out, prefix=".smafl-write-probe.")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        for d in reversed(created):
            with contextlib.suppress(OSError):
                d.rmdir()
        raise UserInputError(f"cannot write to output folder {out}: {_os_message(exc)}") from None
    if existing and announce:
        shown = ", ".join(existing[:6]) + (" ..." if len(existing) > 6 else "")
        msg = f"note: {out} already holds results ({shown}); files of the same name will be replaced"
        # library code logs: the command line shows it (`_progress.shown_on_stderr`); from Python, with no logging
        # configured, Python's last-resort handler shows it on stderr
        logging.getLogger(__name__).warning(msg)
    return out


def leftovers_note(out: str | os.PathLike, since: float) -> str | None:
    """A note naming the files in ``out`` that this run did not write (modified before ``since``), else None.

    A rerun into a folder replaces the files of the same name; the others (figures of an earlier run made with
    figures, then a rerun with ``--no-figures``; a figure another model class drew) stay beside the new fit.json
    and would be read as this run's.  They are named, never removed: they are the user's earlier results.
    """
    out = Path(out)
    try:
        old = sorted(p.name for p in out.iterdir() if not p.name.startswith(".") and p.is_file() and p.stat().st_mtime < since)
    except OSError:
        return None
    if not old:
        return None
    shown = ", ".join(old[:6]) + (f" and {len(old) - 6} more" if len(old) > 6 else "")
    return f"note: {out} still holds {shown} from an earlier run: this run did not write {'it' if len(old) == 1 else 'them'}"


def check_record_magnitude(record):
    """`UserInputError` when a record's input or output is so large that squared errors overflow float64.

    Least squares, RMSE and the likelihoods all sum squares; with values beyond
    ~1e150 those are infinite and every fit or chain would be meaningless.
    """
    n = max(len(record.u), 1)
    for what, name, x in (("input", record.input_name, record.u), ("output", record.output_name, record.y)):
        if x is None:
            continue
        x = np.asarray(x, dtype=np.float64)
        peak = float(np.max(np.abs(x))) if x.size else 0.0
        if not math.isfinite(peak) or peak * peak * n > sys.float_info.max / 16:  # 16: room for residuals of ~4x the data
            raise UserInputError(
                f"{record.path or 'record'}, column '{name}': {what} values up to {peak:.3g} are too large for float64 "
                "least squares (their squares overflow); rescale the column to other units"
            )
