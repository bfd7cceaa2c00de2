"""A spring-mass system split across processes (docs/coupling-schemes.md
§4, test T2): the road body of the force-driven indentation (mass m, pushed by
F, in the coupler) against two block_stub springs k1, k2 (two processes of
one role, freely named, whose forces add). Checked against the analytic
solutions of the discrete schemes, u = d - F'/K, K = k1 + k2, h = w dt,
w^2 = K/m:

The road body starts at rest at d = 0 with no contact force known (the
first step pushes it with F alone); the springs are pre-engaged (gap < 0)
so that they stay linear, force = k (d - gap), F' = F + K gap.
- serial and parallel: central differences with the force at d_{k-1} (the
  blocks answer for the road they were given): u_n = A cos(n th) +
  B sin(n th), cos th = 1 - h^2/2, from u_0 and u_1 (d_1 = dt^2 F/m); both
  schemes give the same numbers (the road body is the coupler's own action,
  so nothing lags);
- implicit: the trapezoidal rule (Newmark average acceleration) with the
  force at d_k, iterated to the tolerance: after the first step, u_n =
  u_1 cos((n-1) th') + (v_1/w) sin((n-1) th'), tan(th'/2) = h/2 (energy
  conserving); the same with each accelerator, and IQN-ILS reaches the
  fixed point of this one-unknown affine interface at the third evaluation
  of the first step (relaxation, then one secant step), at most that
  afterwards, while constant relaxation and Aitken need more."""
import numpy as np

from common import check, columns, done, h5, no_orphans, run, scene

K1, K2, M, F = 1.0e5, 3.0e5, 0.4, 200.0
K = K1 + K2
W = np.sqrt(K / M)
DT = 1.0 / W  # h = 1: a strongly coupled interface
N = 400


def run_scheme(scheme, accel="iqn-ils", tol=1e-12, gap=0.0):
    s = scene(f"road_{scheme}_{accel}", {
        "left": {"exec": "block_stub", "stiffness": K1, "gap": gap},
        "right": {"exec": "block_stub", "stiffness": K2, "gap": gap}},
        scenario={"kind": "indentation", "profile": "force", "road_mass": M, "road_force": F})
    s["time"] = {"dt": DT, "end": N * DT}
    s["coupling"]["scheme"] = scheme
    s["coupling"]["implicit"] = {"tolerance": tol, "acceleration": accel, "max_iterations": 200}
    rc, out, err = run(s, "--quiet")
    check(rc == 0, f"{scheme}/{accel}: run ok ({err[-300:]})")
    no_orphans(s, f"road {scheme}")
    f = h5(s)
    left, right = f["/left/series"][:], f["/right/series"][:]
    cs = f["/coupler/series"][:]
    it = cs[:, columns(f["/coupler/series"]).index("iterations")]
    conv = cs[:, columns(f["/coupler/series"]).index("converged")]
    check(np.array_equal(left[:, 1], right[:, 1]), f"{scheme}: both blocks under one road")
    return left[:, 1], left[:, 2] + right[:, 2], it, conv


n = np.arange(1, N + 1)
# serial / parallel: central differences. A pre-engaged gap keeps both
# springs linear (force = k (d - gap) with d - gap > 0 throughout).
GAP = -1e-4
Fp = F + K * GAP  # force = k (d - gap): m d" = F + K gap - K d
th = np.arccos(1 - 0.5)  # h = 1
h2 = (W * DT) ** 2
u1 = DT ** 2 * F / M - Fp / K
A = -Fp / K
B = (u1 - A * np.cos(th)) / np.sin(th)
d_cd = Fp / K + A * np.cos(n * th) + B * np.sin(n * th)
ser = run_scheme("serial", gap=GAP)
par = run_scheme("parallel", gap=GAP)
err = np.abs(ser[0] - d_cd).max() / (Fp / K)
check(err < 1e-9, f"serial: road displacement = central-difference solution (max rel err {err:.2g})")
check(np.array_equal(ser[0], par[0]) and np.array_equal(ser[1], par[1]),
      "parallel = serial bitwise for the road body (no field lags)")
check(np.allclose(ser[1], K1 * (ser[0] - GAP) + K2 * (ser[0] - GAP), rtol=1e-12),
      "the coupler received the sum of the two springs' forces")
# implicit: trapezoidal rule; first step from a_0 = F/m:
# d_1 = dt^2 (2F + K gap) / (4 m (1 + h^2/4)), v_1 = 2 d_1 / dt
thp = 2 * np.arctan(0.5 * np.sqrt(h2))
d1 = DT ** 2 * (2 * F + K * GAP) / (4 * M * (1 + h2 / 4))
v1 = 2 * d1 / DT
d_tr = Fp / K + (d1 - Fp / K) * np.cos((n - 1) * thp) + v1 / W * np.sin((n - 1) * thp)
results = {}
for accel in ("iqn-ils", "aitken", "constant"):
    d, f, it, conv = run_scheme("implicit", accel=accel, tol=1e-12, gap=GAP)
    results[accel] = (d, it)
    err = np.abs(d - d_tr).max() / (Fp / K)
    check(np.all(conv == 1), f"implicit/{accel}: every step converged")
    check(err < 1e-9, f"implicit/{accel}: d = trapezoidal solution (max rel err {err:.2g})")
    print(f"implicit/{accel}: iterations per step mean {it.mean():.2f}, max {it.max():.0f}")
it_iqn, it_con = results["iqn-ils"][1], results["constant"][1]
check(it_iqn[0] == 3, f"IQN-ILS: the first step converges at the third evaluation ({it_iqn[0]})")
check(it_iqn[1:].max() <= 3, f"IQN-ILS: at most 3 evaluations afterwards ({it_iqn.max()})")
check(it_iqn.sum() < it_con.sum() and it_iqn.sum() < results["aitken"][1].sum(),
      f"IQN-ILS needs fewer iterations ({it_iqn.sum():.0f}) than constant relaxation "
      f"({it_con.sum():.0f}) and Aitken ({results['aitken'][1].sum():.0f})")
# the explicit scheme's period is shorter than the implicit one's: the
# two schemes differ, and each matches its own analysis
check(np.abs(ser[0] - d_tr).max() / (Fp / K) > 1e-2, "serial and implicit differ (different integrators)")
done()
