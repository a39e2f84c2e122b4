"""Probe: threshold spacing of the EUPI grid on the random-cell panel (one-mode cascade on each cell's first 70 %).

python .notes/session59/grid_panel.py OUT.jsonl VARIANT[,VARIANT] SEED...
Kept as the command session 59's results cite; the probe itself (with these variants and session 60's octave ones) is
.notes/session60/grid_panel.py.
"""
import runpy
from pathlib import Path

runpy.run_path(str(Path(__file__).resolve().parents[1] / "session60" / "grid_panel.py"), run_name="__main__")
