"""Our side of the identification benchmark: `smafl_jax.fit` of the cascade in a fresh process.

Prints one JSON line: cold fit time (JIT compilation included, as for jax-sysid),
warm re-fit time, train and held-out RMSE.
"""

import json
import sys
import time

import numpy as np

import smafl_jax as sj


def main():
    tr, te = sj.load_record(sys.argv[1]), sj.load_record(sys.argv[2])
    # paper's identified thermal lag as the starting point, documented EUPI grid
    m0 = sj.Cascade(sj.JouleThermal(sj.PAPER_K1, sj.PAPER_K2), sj.EUPI.from_range(0.0, float(np.max(tr.u))))
    t0 = time.perf_counter()
    res = sj.fit(m0, tr)
    t_cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    sj.fit(m0, tr)
    t_warm = time.perf_counter() - t0
    y_tr = np.asarray(sj.simulate(res.model, tr.u, tr.dt))
    y_te = np.asarray(sj.simulate(res.model, te.u, te.dt))
    print(
        json.dumps(
            {
                "fit_s": t_cold,
                "fit_warm_s": t_warm,
                "converged": res.converged,
                "n_steps": res.n_steps,
                "train_rmse": sj.rmse(tr.y, y_tr).item(),
                "test_rmse": sj.rmse(te.y, y_te).item(),
                "n_params": int(sum(np.size(x) for x in [res.model.hysteresis.v, res.model.hysteresis.w])) + 5,
            }
        )
    )


if __name__ == "__main__":
    main()
