"""Session 27: the smafl command line of the checkout ROOT (a git worktree).  python runcli.py ROOT fit REC.csv --no-figures --out OUT"""
import re, sys
sys.path.insert(0, sys.argv.pop(1))
import smafl_jax
assert smafl_jax.__file__.startswith(sys.path[0]), smafl_jax.__file__
from smafl_jax.cli import main
sys.exit(main())
