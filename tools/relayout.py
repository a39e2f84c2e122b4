#!/usr/bin/env python
"""Issue 12: move the flat private modules of `smafl_jax` into sub-packages by concept.

Run once, from a clean checkout (everything committed), then review ``git status`` and commit:

    python tools/relayout.py            # does the move (git mv), rewrites imports, formats, checks
    python tools/relayout.py --dry-run  # prints the plan, changes nothing

What it does (mapping table below; tools/RELAYOUT.md explains the choices):

1. refuses to run when the tree has uncommitted changes, when it is already moved, or when a
   ``smafl_jax/_*.py`` exists that the table does not name (add it to MOVES, MERGED or KEEP);
2. ``git mv`` every module in MOVES (base names keep their leading underscore: the sub-package is the
   documented API, and a module named like the function it holds, ``identify/fit.py`` beside
   ``identify.fit``, would be shadowed by that function); ``git rm`` the compatibility modules in MERGED;
3. rewrites, with `ast` positions (never a regex over code), every import of a moved module: relative
   imports inside the package (module level or inside functions, ``from . import _x`` included, split
   when one statement names modules that now live in different places) and ``from smafl_jax import _x``
   in tests, experiments and benchmarks; the module-name strings of the lazy tables (`_LAZY` in
   ``smafl_jax/__init__.py``, `HYSTERESIS` in ``_choices.py``); ``Path(__file__).parents[n]`` in moved
   modules (one level deeper);
4. rewrites the dotted names ``smafl_jax._x`` and paths ``smafl_jax/_x.py`` in every tracked text file
   (code, docstrings, strings such as ``monkeypatch`` targets, README, benchmarks) except ``.notes/``
   (history) and this tool;
5. writes each new sub-package's ``__init__.py`` (what the concept is, and re-exports of its modules'
   ``__all__``), extends ``identify/__init__.py``;
6. sorts the imports (ruff, rule I) and formats the files it changed, then checks that ``import smafl_jax``
   works, that every name of ``smafl_jax.__all__`` resolves and that ``__all__`` is unchanged.
"""

from __future__ import annotations

import argparse
import ast
import os
import re
import subprocess
import sys
from pathlib import Path

PKG = "smafl_jax"

# Sub-packages: name -> (docstring, re-export the modules' __all__ from the sub-package).
SUBPACKAGES = {
    "models": (
        "Model classes (equinox PyTrees) and what every model needs.\n\n"
        "The hysteresis protocol (`AbstractHysteresis`) and its models (`EUPI`, `Preisach`), the Joule thermal lag\n"
        "(`JouleThermal`), the paper's eq. (7) model (`JouleLag`), the `Cascade`, the play operators and the\n"
        "models' evaluation-method rule, positivity constraints, initial-state rules, the jitted `simulate`\n"
        "entry points, padded calls and trained-range checks.",
        True,
    ),
    "identify": (
        "Identification: fitting a model to measured records (issue 12).\n\n"
        "The fit itself (profiled initialiser + joint refinement), the automatic start (structure, output\n"
        "orientation, thermal start), the linear solver shared by fit, diagnose and the Preisach cross-validation,\n"
        "train/validation splits, the decimated view of long records, several records at once,\n"
        "recalibration on a new run, the baselines set beside every fit and the error metrics.",
        True,
    ),
    "bayes": (
        "Bayesian uncertainty of an identified model: priors, log-posterior, vectorised emcee runs, diagnostics.",
        True,
    ),
    "control": (
        "Closed-loop control: the cascade plant under PID / composite PID (I-I compensator), batched sweeps\n"
        "over configurations (vmap, sharded over devices) and the multi-process start-up for sweeps past one machine.",
        True,
    ),
    "diagnosis": (
        "Residual diagnosis (`smafl diagnose`): the base model, residual statistics, attribution of the\n"
        "catalogue effects and the generic, labelled correction when the residual stays unexplained.\n\n"
        "(Named ``diagnosis`` because ``smafl_jax.diagnose`` is the public function.)",
        True,
    ),
    "report": (
        "Writing results: fit and diagnosis outputs (fit.json, report.md / report.html, figures), the small\n"
        "report builder, the uncertainty figures and the provenance header of every fit.json-format file.",
        True,
    ),
    "paper": ("`smafl paper`: the paper's whole story on the bundled records, in one run and one report.", True),
    # existing sub-package: `_data` (the CLI's loading entry point) joins it; not re-exported, because
    # `smafl_jax.data.load_record` is `data.load.load_record` and `smafl_jax.load_record` the wrapper in `_data`.
    "data": (None, False),
}

# Old module (relative to the package) -> new module.  Base names are kept.
MOVES = {
    # models
    "_hysteresis": "models._hysteresis",
    "_eupi": "models._eupi",
    "_preisach": "models._preisach",
    "_thermal": "models._thermal",
    "_joule_lag": "models._joule_lag",
    "_cascade": "models._cascade",
    "_operators": "models._operators",
    "_constraints": "models._constraints",
    "_initial_state": "models._initial_state",
    "_simulate": "models._simulate",
    "_padding": "models._padding",
    "_range": "models._range",
    # identify (identify/linear.py is there already)
    "_fit": "identify._fit",
    "_choose": "identify._choose",
    "_split": "identify._split",
    "_decimate": "identify._decimate",
    "_multi_record": "identify._multi_record",
    "_recalibrate": "identify._recalibrate",
    "_baselines": "identify._baselines",
    "_metrics": "identify._metrics",
    # bayes
    "_bayes": "bayes._bayes",
    # control
    "_control": "control._control",
    "_sweep": "control._sweep",
    "_distributed": "control._distributed",
    # diagnosis
    "_diagnose": "diagnosis._diagnose",
    "_residuals": "diagnosis._residuals",
    "_unexplained": "diagnosis._unexplained",
    # report (`_provenance` first: `versions`, which `_report` and `_report_fit` re-export, is re-exported from it)
    "_provenance": "report._provenance",
    "_report": "report._report",
    "_report_fit": "report._report_fit",
    "_reportdoc": "report._reportdoc",
    "_plots_bayes": "report._plots_bayes",
    # paper
    "_paper": "paper._paper",
    # data
    "_data": "data._data",
}

# Compatibility modules that only re-export a sub-package: removed, their importers use the sub-package.
MERGED = {"_effects": "effects"}

# Cross-cutting modules that stay at the top: imported by every sub-package and by the JAX-free command
# paths (`smafl --help`, `smafl check`), so they must not sit in a sub-package whose __init__ imports JAX.
KEEP = {"_config", "_errors", "_io", "_progress", "_choices"}

# Module-name strings the package resolves itself: (file, name of the dict whose string values are
# module names relative to the package, optionally followed by ":Class").
STRING_TABLES = [(f"{PKG}/__init__.py", "_LAZY"), (f"{PKG}/_choices.py", "HYSTERESIS")]

# Top-level definitions that nothing uses (found for issue 12): removed while the definition is the only
# occurrence of the name in the repository's code and docs; kept, with a note, once something uses it.
DEAD = [
    (f"{PKG}/_diagnose.py", "linear_init"),  # superseded by profile_gains
    (f"{PKG}/_diagnose.py", "synthetic_strength"),  # the catalogue classes carry `synthetic` themselves
    (f"{PKG}/_preisach.py", "_n_from_weights"),
    (f"{PKG}/_range.py", "RAW_RULE"),  # only EFFECTIVE_RULE is written to fit.json
    (f"{PKG}/cli/simulate.py", "parse_calibrate"),  # the workflow parses --calibrate (parse_segment)
]

TEXT_SUFFIXES = {".py", ".md", ".rst", ".txt", ".toml", ".cfg", ".ini", ".yml", ".yaml"}
SKIP_PREFIXES = (".notes/", "tools/relayout.py", "tools/RELAYOUT.md")

OLD_DOC = "Models (PyTrees), operators, data loading and metrics are re-exported here;\nthe modules behind them are private."
NEW_DOC = (
    "The public names are re-exported here from the sub-packages, one per concept: `models`, `identify`,\n"
    "`bayes`, `control`, `diagnosis`, `report`, `paper`, `data`, `ops`, `effects`, `workflows`, `cli`\n"
    "(see each one's docstring); the modules inside them are private."
)


class Refused(SystemExit):
    pass


def refuse(msg: str):
    raise Refused(f"relayout: refused: {msg}")


def git(root: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=root, check=True, capture_output=True, text=True).stdout


# --- plan --------------------------------------------------------------------------------------------


def module_map() -> dict[str, str]:
    """Absolute old module -> absolute new module (moves and merges)."""
    out = {f"{PKG}.{old}": f"{PKG}.{new}" for old, new in MOVES.items()}
    out.update({f"{PKG}.{old}": f"{PKG}.{new}" for old, new in MERGED.items()})
    return out


def map_module(name: str, mm: dict[str, str]) -> str:
    for old, new in mm.items():
        if name == old or name.startswith(old + "."):
            return new + name[len(old) :]
    return name


def check_tree(root: Path, allow_untracked: bool, dry_run: bool = False) -> list[str]:
    """Refuse on a dirty, already-moved or unknown tree; return the files to rewrite."""
    if not (root / PKG / "__init__.py").is_file() or not (root / ".git").exists():
        refuse(f"{root} is not the root of a smafl-jax git checkout")
    dirty = [ln for ln in git(root, "status", "--porcelain").splitlines() if ln and not ln.startswith("??")]
    if dirty and dry_run:
        print("relayout: dry run on uncommitted changes (the real run refuses them):\n  " + "\n  ".join(dirty))
    elif dirty:
        refuse("uncommitted changes (commit them first):\n  " + "\n  ".join(dirty))
    untracked = git(root, "ls-files", "--others", "--exclude-standard").split()
    if untracked and dry_run and not allow_untracked:
        print("relayout: dry run; untracked files are not rewritten (the real run refuses them):\n  " + "\n  ".join(untracked))
    elif untracked and not allow_untracked:
        refuse("untracked files (commit them, or pass --allow-untracked to rewrite them too):\n  " + "\n  ".join(untracked))
    subs = [s for s, (doc, _) in SUBPACKAGES.items() if doc is not None]
    existing = [s for s in subs if (root / PKG / s).exists() and s != "identify"]
    missing = [m for m in [*MOVES, *MERGED] if not (root / PKG / f"{m}.py").exists()]
    if existing or missing:
        refuse(
            "the tree looks already moved (or moved in part): "
            + (f"sub-packages present: {existing}; " if existing else "")
            + (f"modules absent: {missing}" if missing else "")
        )
    known = set(MOVES) | set(MERGED) | set(KEEP)
    unknown = sorted(p.stem for p in (root / PKG).glob("_*.py") if p.stem not in known and not p.stem.startswith("__"))
    if unknown:
        refuse(
            "private modules missing from the mapping table (add each to MOVES, MERGED or KEEP in tools/relayout.py):\n  "
            + "\n  ".join(f"{PKG}/{u}.py" for u in unknown)
        )
    for old in MOVES:
        if (root / new_path(f"{PKG}/{old}.py")).exists():
            refuse(f"destination exists: {new_path(f'{PKG}/{old}.py')}")
    for name in SUBPACKAGES:
        if name in _public_names(root):
            refuse(f"sub-package name {name!r} is a public name of smafl_jax; importing it would shadow that name")
    files = git(root, "ls-files").split() + (untracked if allow_untracked else [])
    return [f for f in files if Path(f).suffix in TEXT_SUFFIXES and not f.startswith(SKIP_PREFIXES) and (root / f).is_file()]


def _public_names(root: Path) -> list[str]:
    tree = ast.parse((root / PKG / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return list(ast.literal_eval(node.value))
    return []


def old_modules(root: Path) -> set[str]:
    """Every importable module and package name under the package, as it is before the move."""
    out = set()
    for p in (root / PKG).rglob("*.py"):
        parts = p.relative_to(root).with_suffix("").parts
        out.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def new_path(rel: str) -> str:
    """Repository path of a file after the move (unchanged when it does not move)."""
    p = Path(rel)
    if p.parent == Path(PKG) and p.stem in MOVES:
        return f"{PKG}/{MOVES[p.stem].replace('.', '/')}.py"
    return rel


def module_of(rel: str) -> str | None:
    parts = Path(rel).with_suffix("").parts
    if parts[0] != PKG:
        return None
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_of(rel: str) -> str:
    """The package relative imports of file ``rel`` resolve against."""
    parts = Path(rel).with_suffix("").parts
    return ".".join(parts[:-1])


# --- rewriting ---------------------------------------------------------------------------------------


class Source:
    """A file's bytes with edits at `ast` positions (applied last to first)."""

    def __init__(self, text: str):
        self.data = text.encode()
        self.starts = [0]
        for i, b in enumerate(self.data):
            if b == 10:
                self.starts.append(i + 1)
        self.edits: list[tuple[int, int, str]] = []

    def span(self, node) -> tuple[int, int]:
        return self.starts[node.lineno - 1] + node.col_offset, self.starts[node.end_lineno - 1] + node.end_col_offset

    def segment(self, node) -> str:
        a, b = self.span(node)
        return self.data[a:b].decode()

    def indent(self, node) -> str:
        a, _ = self.span(node)
        return self.data[self.starts[node.lineno - 1] : a].decode()

    def replace(self, node, text: str):
        a, b = self.span(node)
        self.edits.append((a, b, text))

    def result(self) -> str:
        data = self.data
        for a, b, text in sorted(self.edits, reverse=True):
            data = data[:a] + text.encode() + data[b:]
        return data.decode()


def relative(target: str, package: str) -> str:
    """``from <this> import`` text for module ``target`` seen from ``package``."""
    t, p = target.split("."), package.split(".")
    common = 0
    while common < min(len(t), len(p)) and t[common] == p[common]:
        common += 1
    return "." * (len(p) - common + 1) + ".".join(t[common:])


def rewrite_imports(src: Source, tree: ast.AST, old_rel: str, new_rel: str, mm: dict[str, str], modules: set[str], notes):
    """Rewrite every ``from X import ...`` of a moved module; return the number of statements changed."""
    old_pkg, new_pkg = package_of(old_rel), package_of(new_rel)
    changed = 0
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            if module_of(old_rel) is None:
                continue  # relative import outside the package (tests' own helpers)
            base = old_pkg.split(".")[: len(old_pkg.split(".")) - (node.level - 1)]
            base = ".".join(base + ([node.module] if node.module else []))
        elif node.module and (node.module == PKG or node.module.startswith(PKG + ".")):
            base = node.module
        else:
            continue
        groups: dict[str, list[ast.alias]] = {}
        renamed = False
        for alias in node.names:
            full = f"{base}.{alias.name}"
            if alias.name != "*" and full in modules:  # a module imported by name: it may move on its own
                new_full = map_module(full, mm)
                parent, _, leaf = new_full.rpartition(".")
                if leaf != alias.name:
                    renamed = True
                    alias = ast.alias(name=leaf, asname=alias.asname or alias.name)
                groups.setdefault(parent, []).append(alias)
            else:
                groups.setdefault(map_module(base, mm), []).append(alias)
        texts = {g: (relative(g, new_pkg) if node.level else g) for g in groups}
        old_from = re.match(r"from\s+([.\w]+)\s+import", src.segment(node))
        if old_from is None:
            notes.append(f"{new_rel}:{node.lineno}: import not understood, left as is: {src.segment(node)!r}")
            continue
        if len(groups) == 1 and not renamed:
            (new_from,) = texts.values()
            if new_from != old_from.group(1):
                seg = src.segment(node)
                src.replace(node, seg[: old_from.start(1)] + new_from + seg[old_from.end(1) :])
                changed += 1
            continue
        pieces = []
        for g, aliases in groups.items():
            frm = texts[g]
            level = len(frm) - len(frm.lstrip("."))
            pieces.append(ast.unparse(ast.ImportFrom(module=frm[level:] or None, names=aliases, level=level)))
        if "#" in src.segment(node):
            notes.append(f"{new_rel}:{node.lineno}: comments inside a split import were dropped")
        src.replace(node, ("\n" + src.indent(node)).join(pieces))
        changed += 1
    return changed


def remove_dead(text: str, rel: str, corpus: str, notes) -> str:
    """Drop the DEAD definitions of file ``rel`` whose name occurs nowhere else in ``corpus``."""
    lines = text.splitlines(keepends=True)
    drop = []
    for path, name in DEAD:
        if path != rel:
            continue
        uses = len(re.findall(rf"\b{re.escape(name)}\b", corpus))
        node = next((n for n in ast.parse(text).body if _defines(n, name)), None)
        if node is None:
            notes.append(f"{rel}: {name} (dead code) not found; nothing removed")
        elif uses != 1:
            notes.append(f"{rel}: {name} is used now ({uses - 1} other occurrences); kept")
        else:
            first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
            drop.append((first, node.end_lineno))
            notes.append(f"{rel}: removed unused {name} (lines {first}-{node.end_lineno})")
    for first, last in sorted(drop, reverse=True):
        del lines[first - 1 : last]
    return "".join(lines)


def _defines(node, name: str) -> bool:
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return node.name == name
    if isinstance(node, (ast.Assign, ast.AnnAssign)):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        return any(getattr(t, "id", None) == name for t in targets)
    return False


def rewrite_string_tables(src: Source, tree: ast.AST, table: str, rel: str) -> int:
    """Module-name strings (``"_fit"``, ``"_eupi:EUPI"``) in the dict ``table`` of the package."""
    changed = 0
    for node in ast.walk(tree):
        value = None
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == table for t in node.targets):
            value = node.value
        elif isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == table:
            value = node.value
        if not isinstance(value, ast.Dict):
            continue
        for v in value.values:
            if not (isinstance(v, ast.Constant) and isinstance(v.value, str)):
                continue
            mod, sep, rest = v.value.partition(":")
            new = map_module(f"{PKG}.{mod}", module_map())[len(PKG) + 1 :]
            if new != mod:
                quote = src.segment(v)[0]
                src.replace(v, f"{quote}{new}{sep}{rest}{quote}")
                changed += 1
    if not changed:
        raise SystemExit(f"relayout: {rel}: found no module-name strings in {table}; update STRING_TABLES")
    return changed


FILE_PARENTS = re.compile(r"(Path\(__file__\)(?:\.resolve\(\))?\.parents\[)(\d+)(\])")


def rewrite_file_paths(text: str, rel: str, depth: int, notes) -> str:
    """``Path(__file__).parents[n]`` in a module moved ``depth`` levels deeper."""
    text = FILE_PARENTS.sub(lambda m: f"{m.group(1)}{int(m.group(2)) + depth}{m.group(3)}", text)
    rest = FILE_PARENTS.sub("", text)
    if "__file__" in rest:
        notes.append(f"{rel}: uses __file__ in a form this tool does not adjust: check it by hand")
    return text


def text_patterns() -> list[tuple[re.Pattern, str]]:
    pats = []
    for old, new in {**MOVES, **MERGED}.items():
        pats.append((re.compile(rf"\b{PKG}\.{old}\b"), f"{PKG}.{new}"))
        dest = f"{PKG}/{new.replace('.', '/')}" + (".py" if old in MOVES else "/__init__.py")
        pats.append((re.compile(rf"\b{PKG}/{old}\.py\b"), dest))
    return pats


def stray_strings(tree: ast.AST, rel: str, notes):
    """Warn about strings naming a moved module in a form the tool does not rewrite."""
    olds = set(MOVES) | set(MERGED)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            v = node.value
            if v.partition(":")[0] in olds or re.search(r"(?<![\w])\.(" + "|".join(olds) + r")\b", v):
                if not re.search(rf"\b{PKG}\.", v):
                    notes.append(f"{rel}:{node.lineno}: string {v[:60]!r} may name a moved module: check it")


# --- sub-package __init__ files -----------------------------------------------------------------------


def module_all(text: str) -> list[str] | None:
    for node in ast.parse(text).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return list(ast.literal_eval(node.value))
    return None


def lazy_names(init_text: str) -> dict[str, list[str]]:
    """Old module -> public names the top-level `_LAZY` table takes from it (for modules without __all__)."""
    out: dict[str, list[str]] = {}
    for node in ast.parse(init_text).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_LAZY" for t in node.targets):
            for k, v in ast.literal_eval(node.value).items():
                out.setdefault(v, []).append(k)
    return out


def init_text(sub: str, doc: str, contents: dict[str, str], lazy: dict[str, list[str]], existing: str | None, notes) -> str:
    """The ``__init__.py`` of sub-package ``sub``: docstring, re-exports of its moved modules, ``__all__``."""
    body, names = [], []
    if existing is not None:  # keep what the sub-package already had (imports, other statements)
        tree = ast.parse(existing)
        lines = existing.splitlines(keepends=True)
        for node in tree.body:
            if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
                continue  # old docstring
            if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
                names += ast.literal_eval(node.value)
                continue
            body.append("".join(lines[node.lineno - 1 : node.end_lineno]).rstrip("\n"))
    seen = dict.fromkeys(names, "existing")
    for old, new in MOVES.items():
        if not new.startswith(sub + "."):
            continue
        leaf = new.split(".")[-1]
        public = module_all(contents[new]) or lazy.get(old, [])
        take = []
        for n in public:
            if n in seen:
                notes.append(f"{PKG}.{sub}: {n!r} of {leaf} is already exported from {seen[n]}; not exported twice")
                continue
            seen[n] = leaf
            take.append(n)
        if take:
            body.append(f"from .{leaf} import {', '.join(take)}")
            names += take
    all_text = "__all__ = [\n" + "".join(f'    "{n}",\n' for n in names) + "]\n"
    return f'"""{doc}\n"""\n\n' + "\n".join(body) + "\n\n" + all_text


# --- main --------------------------------------------------------------------------------------------


def run_checks(root: Path, public_before: list[str]) -> list[str]:
    problems = []
    public_after = _public_names(root)
    if public_before != public_after:
        problems.append(f"smafl_jax.__all__ changed: {sorted(set(public_before) ^ set(public_after))}")
    code = (
        "import importlib, smafl_jax as sj\n"
        f"assert sj.__file__.startswith({str(root)!r}), sj.__file__\n"
        "sj._load_all()\n"
        "bad = [n for n in sj.__all__ if not hasattr(sj, n)]\n"
        "assert not bad, bad\n"
        f"for s in {[*SUBPACKAGES, 'ops', 'effects', 'workflows', 'cli']!r}:\n"
        "    m = importlib.import_module('smafl_jax.' + s)\n"
        "    bad = [n for n in getattr(m, '__all__', []) if not hasattr(m, n)]\n"
        "    assert not bad, (s, bad)\n"
        "print('ok')\n"
    )
    env = {**os.environ, "PYTHONPATH": str(root) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    r = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True)
    if r.returncode != 0 or r.stdout.strip() != "ok":
        problems.append("import check failed:\n" + r.stdout + r.stderr)
    return problems


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[1], help="checkout root (default: this tool's)")
    ap.add_argument("--dry-run", action="store_true", help="print the plan and change nothing")
    ap.add_argument("--allow-untracked", action="store_true", help="run with untracked files present (they are rewritten too)")
    ap.add_argument("--no-format", action="store_true", help="skip ruff (import sorting, formatting)")
    args = ap.parse_args(argv)
    root = args.repo.resolve()
    files = check_tree(root, args.allow_untracked, args.dry_run)
    mm = module_map()
    modules = old_modules(root)
    public_before = _public_names(root)

    print(f"relayout: {root}")
    for old in MOVES:
        print(f"  move   {PKG}/{old}.py -> {new_path(f'{PKG}/{old}.py')}")
    for old, new in MERGED.items():
        print(f"  remove {PKG}/{old}.py (compatibility module; importers now use {PKG}.{new})")
    print(f"  keep   {', '.join(f'{PKG}/{k}.py' for k in sorted(KEEP))}")

    # 1. new contents of every text file, computed on the tree before the move
    notes: list[str] = []
    pats = text_patterns()
    tables = dict(STRING_TABLES)
    new_contents: dict[str, str] = {}
    corpus = "\n".join((root / f).read_text(encoding="utf-8") for f in files)
    for rel in files:
        if Path(rel).stem in MERGED and Path(rel).parent == Path(PKG):
            continue
        text = (root / rel).read_text(encoding="utf-8")
        dest = new_path(rel)
        if any(path == rel for path, _ in DEAD):
            text = remove_dead(text, rel, corpus, notes)
        if rel.endswith(".py"):
            try:
                tree = ast.parse(text)
            except SyntaxError as exc:
                notes.append(f"{rel}: not parsed ({exc}); only dotted names rewritten")
                tree = None
            if tree is not None:
                src = Source(text)
                rewrite_imports(src, tree, rel, dest, mm, modules, notes)
                if rel in tables:
                    rewrite_string_tables(src, tree, tables[rel], rel)
                elif module_of(rel):
                    stray_strings(tree, rel, notes)
                text = src.result()
            if dest != rel:
                text = rewrite_file_paths(text, dest, len(Path(dest).parts) - len(Path(rel).parts), notes)
        for pat, repl in pats:
            text = pat.sub(repl, text)
        if rel == f"{PKG}/__init__.py":
            if OLD_DOC in text:
                text = text.replace(OLD_DOC, NEW_DOC)
            else:
                notes.append(f"{rel}: docstring sentence about private modules not found; left as is")
        if text != (root / rel).read_text(encoding="utf-8") or dest != rel:
            new_contents[dest] = text

    lazy = lazy_names((root / PKG / "__init__.py").read_text())
    by_module = {new: new_contents.get(new_path(f"{PKG}/{old}.py")) for old, new in MOVES.items()}
    for old, new in MOVES.items():
        if by_module[new] is None:
            by_module[new] = (root / PKG / f"{old}.py").read_text()
    inits: dict[str, str] = {}
    for sub, (doc, export) in SUBPACKAGES.items():
        path = f"{PKG}/{sub}/__init__.py"
        if not export:
            continue
        existing = new_contents.get(path) or ((root / path).read_text() if (root / path).exists() else None)
        inits[path] = init_text(sub, doc, by_module, lazy, existing, notes)

    if args.dry_run:
        print(f"  would rewrite {len(new_contents)} files and write {len(inits)} sub-package __init__ files")
        for n in notes:
            print(f"  note (dry run, nothing done): {n}")
        return 0

    # 2. the move itself
    for sub in SUBPACKAGES:
        (root / PKG / sub).mkdir(exist_ok=True)
    for old in MOVES:
        git(root, "mv", f"{PKG}/{old}.py", new_path(f"{PKG}/{old}.py"))
    for old in MERGED:
        git(root, "rm", "-q", f"{PKG}/{old}.py")
    for rel, text in {**new_contents, **inits}.items():
        (root / rel).write_text(text, encoding="utf-8")

    changed_py = sorted(p for p in {*new_contents, *inits} if p.endswith(".py"))
    if not args.no_format:
        ruff = [sys.executable, "-m", "ruff"]
        subprocess.run([*ruff, "check", "--quiet", "--fix", "--select", "I", *changed_py], cwd=root, check=False)
        subprocess.run([*ruff, "format", "--quiet", *changed_py], cwd=root, check=True)

    print(f"  rewrote {len(new_contents)} files, wrote {len(inits)} sub-package __init__ files:")
    for rel in sorted({*new_contents, *inits}):
        print(f"    {rel}")
    for n in notes:
        print(f"  note: {n}")
    problems = run_checks(root, public_before)
    for p in problems:
        print(f"  PROBLEM: {p}")
    if problems:
        print("relayout: moved, but the checks above failed: fix them (or reset the checkout) before committing")
    else:
        print("relayout: done; review `git status` / `git diff -M --stat`, run ruff and the tests, then commit")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
