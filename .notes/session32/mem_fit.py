"""Peak RSS of a few full-rate LM steps (the polish) of a fitted model on the first n samples of a record."""
import sys, resource, time
sys.path.insert(0, sys.argv[1])
import numpy as np
import smafl_jax as sj
model = sj.load_model(sys.argv[2])
rec = sj.load_record(sys.argv[3])
n = int(sys.argv[4])
import numpy as _np; rec = rec.take(_np.arange(n)) if n < len(rec.y) else rec
r0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
t = time.time()
spec = sj.default_trainable(model)
res = sj.fit(model, rec, solver='lm', trainable=spec, init=None, max_steps=5)
print(n, 'rss before %.2f GB, peak %.2f GB' % (r0, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6), 'loss %.6g -> %.6g' % (res.init_loss, res.loss), '%.0f s' % (time.time() - t))
