"""Command-line interface: ``smafl <command> ...``.

Each command lives in its own module here with ``add_parser(subparsers)``
registering a parser whose ``func`` runs it.  User errors (`UserInputError`)
are printed as one line without a traceback and exit with code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .._errors import UserInputError

# Command modules, in the order `smafl --help` lists them.
COMMANDS = ["simulate", "fit", "sample", "control", "sweep", "diagnose", "paper", "check"]


def build_parser():
    parser = argparse.ArgumentParser(
        prog="smafl",
        description="System identification, uncertainty and control for hysteretic thermal artificial muscles.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"{__name__}.{name}").add_parser(sub)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserInputError as exc:
        print(f"smafl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"smafl {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
