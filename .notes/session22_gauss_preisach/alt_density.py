"""Plant-B records with Preisach densities that are NOT one bivariate Gaussian (oracle generalisation check).
Swaps indep_plant_b.PreisachGauss's density: 'mix' = two Gaussians (random weights and positions), 'cauchy' =
product of Lorentzians in (alpha, beta) (heavy tails), 'skew' = lognormal in the width (loop widths skewed)."""
import sys, json, numpy as np
sys.path[:0]=[__import__('os').path.dirname(__import__('os').path.abspath(__file__)),'/work/main/experiments','/work/main/tests']
import indep_plant_b as pb
from param_oracle import grid_fit, param_fit

KIND = sys.argv[1]
Base = pb.PreisachGauss
class Alt(Base):
    def __init__(self, rng, ta, n=150):
        super().__init__(rng, ta, n)
        aa, bb = self.alpha, self.beta
        if KIND == 'mix':
            a2 = self.a_mean + float(rng.uniform(-12, 12)); b2 = a2 - float(rng.uniform(5, 20))
            s2a, s2b, r2 = float(rng.uniform(2, 6)), float(rng.uniform(2, 6)), float(rng.uniform(-0.3, 0.6))
            p = float(rng.uniform(0.3, 0.7))
            g = lambda am, bm, sa, sb, r: np.exp(-(((aa-am)/sa)**2 - 2*r*((aa-am)/sa)*((bb-bm)/sb) + ((bb-bm)/sb)**2)/(2*(1-r*r)))
            w = p*g(self.a_mean, self.b_mean, self.sd_a, self.sd_b, self.rho) + (1-p)*g(a2, b2, s2a, s2b, r2)
        elif KIND == 'cauchy':
            w = 1/(1+((aa-self.a_mean)/self.sd_a)**2) / (1+((bb-self.b_mean)/self.sd_b)**2)
        elif KIND == 'skew':
            u = (aa+bb)/2; wd = np.maximum(aa-bb, 1e-6); wm = self.a_mean-self.b_mean
            w = np.exp(-((u-(self.a_mean+self.b_mean)/2)/self.sd_a)**2/2) * np.exp(-(np.log(wd/wm)/0.5)**2/2)/wd
        self.w = w / w.sum()
pb.PreisachGauss = Alt

if __name__ == '__main__':
    out = open(sys.argv[3], 'a')
    for seed in [int(s) for s in sys.argv[2].split(',')]:
        for drive, rate, start in [('steps',25,'mid'),('triangle',5,'warm'),('pwm',25,'cold'),('multisine',25,'cold'),('triangle',25,'mid'),('steps',5,'warm')]:
            rec = pb.make_record(seed, drive=drive, rate_hz=rate, start=start, hysteresis='preisach'); tr = rec['truth']
            step = max(1, int(rate // 5)); T = tr['temperature'][::step]; y = rec['output'][::step]; sd = rec['noise_sd']
            h0 = int(round(0.7 * T.size))
            g = grid_fit(T, y, h0); p, th = param_fit(T, y, h0)
            e = lambda q, s: float(np.sqrt(np.mean((q[s] - y[s]) ** 2)) / sd)
            row = dict(kind=KIND, seed=seed, drive=drive, rate=rate, start=start, inside=tr['heldout_T_inside_fraction'],
                       grid_train=e(g, slice(0, h0)), grid_held=e(g, slice(h0, None)), par_train=e(p, slice(0, h0)), par_held=e(p, slice(h0, None)))
            print(f"{KIND:6s} s{seed} {drive:9s} {rate:3d} {start:5s} in {row['inside']:.2f} grid {row['grid_train']:6.2f}/{row['grid_held']:7.2f}  param {row['par_train']:6.2f}/{row['par_held']:7.2f}", flush=True)
            out.write(json.dumps(row) + '\n'); out.flush()
