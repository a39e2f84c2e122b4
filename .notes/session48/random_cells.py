"""Random matrix cells for a smoke run of the default fit (session 48): one cell per seed, printed as JSON lines.

python .notes/session48/random_cells.py SEED...   ->  SEED<TAB>MINUTES<TAB>{cell json}
Draws the drive family, the rate (log-uniform 5-100 Hz), the start and the sensor; minutes 5-20, capped so a record
has at most 60 000 samples (fit time). The plant's structure is random_truth's own draw (memory, thermal scheme...).
"""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
import indep_plant as ip  # noqa: E402

for s in sys.argv[1:]:
    rng = np.random.default_rng([int(s), 4848])
    fam = str(rng.choice(ip.FAMILIES))
    rate = float(np.exp(rng.uniform(np.log(5.0), np.log(100.0))))
    rate = round(rate, 1)
    minutes = float(rng.uniform(5.0, 20.0))
    minutes = round(min(minutes, 60000 / rate / 60.0), 1)
    cell = {"drive": fam, "rate_hz": rate, "start": str(rng.choice(ip.STARTS)), "orientation": str(rng.choice(ip.ORIENTATIONS))}
    name = f"{fam} {cell['start']} {rate:g} Hz {cell['orientation']} {minutes:g} min"
    print(f"{s}\t{minutes}\t{json.dumps({name: cell})}")
