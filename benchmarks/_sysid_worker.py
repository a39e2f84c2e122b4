"""jax-sysid side of the identification benchmark (runs in benchmarks/.sysid-venv).

Fits jax-sysid's documented residual-RNN nonlinear state-space model
(README example: x+ = A x + B u + W3 sigmoid(W1 x + W2 u + b1) + b2,
y = C x + W5 sigmoid(W4 x + b3) + b4; 1000 Adam + up to 1000 L-BFGS
iterations) and a linear state-space model to the training record, then
predicts the held-out record.  Prints one JSON line.  Only numpy + jax_sysid.
"""

import json
import sys
import time

import numpy as np


def load(path):
    d = np.genfromtxt(path, delimiter=",", names=True)
    return d["voltage_V"].astype(float), d["displacement_mm"].astype(float)


def main():
    train, test, nx, epochs = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    import jax
    import jax.numpy as jnp
    from jax_sysid.models import LinearModel, Model

    jax.config.update("jax_enable_x64", True)
    u, y = load(train)
    ut, yt = load(test)
    um, us, ym, ys = u.mean(), u.std(), y.mean(), y.std()
    U, Y = ((u - um) / us)[:, None], ((y - ym) / ys)[:, None]
    Ut = ((ut - um) / us)[:, None]
    out = {"jax": jax.__version__, "n_train": len(u), "n_test": len(ut), "nx": nx}

    def sigmoid(x):
        return 1.0 / (1.0 + jnp.exp(-x))

    @jax.jit
    def state_fcn(x, u, params):
        A, B, C, W1, W2, W3, b1, b2, W4, W5, b3, b4 = params
        return A @ x + B @ u + W3 @ sigmoid(W1 @ x + W2 @ u + b1) + b2

    @jax.jit
    def output_fcn(x, u, params):
        A, B, C, W1, W2, W3, b1, b2, W4, W5, b3, b4 = params
        return C @ x + W5 @ sigmoid(W4 @ x + b3) + b4

    rng = np.random.default_rng(0)
    nnx = nny = 8
    ny = nu = 1
    params = [
        0.5 * np.eye(nx),
        0.1 * rng.normal(size=(nx, nu)),
        0.1 * rng.normal(size=(ny, nx)),
        0.1 * rng.normal(size=(nnx, nx)),
        0.5 * rng.normal(size=(nnx, nu)),
        0.5 * rng.normal(size=(nx, nnx)),
        np.zeros(nnx),
        np.zeros(nx),
        0.5 * rng.normal(size=(nny, nx)),
        0.5 * rng.normal(size=(ny, nny)),
        np.zeros(nny),
        np.zeros(ny),
    ]

    def rmse(a, b):
        return float(np.sqrt(np.mean((np.ravel(a) - np.ravel(b)) ** 2)))

    for name, make in (
        ("nonlinear", lambda: Model(nx, ny, nu, state_fcn=state_fcn, output_fcn=output_fcn)),
        ("linear", lambda: LinearModel(nx, ny, nu)),
    ):
        model = make()
        if name == "nonlinear":
            model.init(params=params)
            model.loss(rho_x0=1e-4, rho_th=1e-4)
            model.optimization(adam_epochs=epochs, lbfgs_epochs=epochs, iprint=-1)
        else:
            model.loss(rho_x0=1e-3, rho_th=1e-2)
            model.optimization(lbfgs_epochs=epochs, iprint=-1)
        t0 = time.perf_counter()
        model.fit(Y, U)
        t_fit = time.perf_counter() - t0
        yhat_tr, _ = model.predict(model.x0, U)
        # held out: the training initial state (both records start at rest at 0 V) ...
        yhat_te, _ = model.predict(model.x0, Ut)
        # ... and the package's own recipe, which estimates x0 from the held-out outputs
        x0t = model.learn_x0(Ut, ((yt - ym) / ys)[:, None], verbosity=False)
        yhat_te2, _ = model.predict(x0t, Ut)
        out[name] = {
            "fit_s": t_fit,
            "train_rmse": rmse(np.asarray(yhat_tr) * ys + ym, y),
            "test_rmse": rmse(np.asarray(yhat_te) * ys + ym, yt),
            "test_rmse_learned_x0": rmse(np.asarray(yhat_te2) * ys + ym, yt),
        }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
