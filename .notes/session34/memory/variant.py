"""Session 34: fit_sets.py with the per-record operator memory switched on (`RECORD_MEMORY`, default off) and
`WIPED_WITHIN` set.   python .notes/session34/memory/variant.py WIPED_WITHIN ROOT OUT.json loro|none SEED[:SET] ..."""

import runpy
import sys
from pathlib import Path

wiped = float(sys.argv.pop(1))
sys.path.insert(0, sys.argv[1])
from smafl_jax.identify import _memory_search as ms  # noqa: E402  private: the switches under test
from smafl_jax.identify import _record_starts as rs  # noqa: E402

rs.RECORD_MEMORY, ms.WIPED_WITHIN = True, wiped
runpy.run_path(str(Path(__file__).with_name("fit_sets.py")), run_name="__main__")
