"""Run the smafl CLI of ROOT with a thread printing RSS (GB) every 2 s when it grew by > 0.5 GB since the last print."""
import sys, threading, time, re
sys.path.insert(0, sys.argv.pop(1))
def rss():
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith('VmRSS'):
                return int(line.split()[1]) / 1e6
    return 0.0
def watch():
    last, peak = 0.0, 0.0
    while True:
        r = rss(); peak = max(peak, r)
        if abs(r - last) > 0.5:
            print(f'## RSS {r:.1f} GB (peak {peak:.1f}) at {time.strftime("%H:%M:%S")}', file=sys.stderr, flush=True); last = r
        time.sleep(1)
threading.Thread(target=watch, daemon=True).start()
from smafl_jax.cli import main
rc = main()
print(f'## final RSS {rss():.1f} GB', file=sys.stderr)
sys.exit(rc)
