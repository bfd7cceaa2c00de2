"""Pictures and numbers for bench/results/green_springs.md (run by run.sh)."""
import os
import sys

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

T, O = sys.argv[1], sys.argv[2]
os.makedirs(O, exist_ok=True)
out = lambda n: os.path.join(O, "green_springs_" + n)
lines = []

# ------------------------------------------------------------------ road
with h5py.File(os.path.join(T, "road.h5")) as f:
    r = f["road"]
    z = r["heights"][:]
    dx = r.attrs["dx"]
    H = r.attrs["hurst"]; lS = r.attrs["lambda_short"]; lL = r.attrs["lambda_long"]
with h5py.File(os.path.join(T, "springs.h5")) as f:
    s = f["springs"]
    zr = s["z_road"][:]
    d, F, k = s["d"][:], s["F"][:], s["k"][:]
    poly = s["poly"][:]
    rd, rF, rk = s["raw_d"][:], s["raw_F"][:], s["raw_k"][:]
    eh, ep = s["err_hermite"][:], s["err_poly"][:]
    rule = s.attrs["film_thickness_rule"]
    rule = rule.decode() if isinstance(rule, bytes) else rule
    rel = s.attrs["release_force"]

fig, ax = plt.subplots(1, 2, figsize=(11, 4.6))
L = z.shape[1] * dx * 1e3
im = ax[0].imshow(z[::4, ::4] * 1e6, origin="lower", extent=[0, L, 0, L], cmap="terrain")
ax[0].set_title(f"generated road, {z.shape[1]}² points at {dx*1e6:.0f} µm (H = {H})")
ax[0].set_xlabel("x (mm)"); ax[0].set_ylabel("y (mm)")
plt.colorbar(im, ax=ax[0], label="height (µm)")
im = ax[1].imshow(zr * 1e6, origin="lower", extent=[0, L, 0, L], cmap="terrain")
ax[1].set_title("20×20 block grid: highest point per element")
ax[1].set_xlabel("x (mm)")
plt.colorbar(im, ax=ax[1], label="z_road (µm)")
fig.tight_layout(); fig.savefig(out("road.png"), dpi=110); plt.close(fig)

# PSD
Z = np.fft.rfft2(z - z.mean())
qy = 2 * np.pi * np.fft.fftfreq(z.shape[0], dx)
qx = 2 * np.pi * np.fft.rfftfreq(z.shape[1], dx)
q = np.hypot(*np.meshgrid(qx, qy))
P = np.abs(Z) ** 2
bins = np.logspace(np.log10(q[q > 0].min()), np.log10(q.max()), 60)
idx = np.digitize(q.ravel(), bins)
qm = np.array([q.ravel()[idx == i].mean() if np.any(idx == i) else np.nan for i in range(1, len(bins))])
Pm = np.array([P.ravel()[idx == i].mean() if np.any(idx == i) else np.nan for i in range(1, len(bins))])
qL, qS = 2 * np.pi / lL, 2 * np.pi / lS
sel = (qm > qL) & (qm < qS) & np.isfinite(Pm) & (Pm > 0)
slope = np.polyfit(np.log(qm[sel]), np.log(Pm[sel]), 1)[0]
fig, ax = plt.subplots(figsize=(6, 4.4))
ax.loglog(qm, Pm, ".", label="radially averaged |FFT|²")
ax.loglog(qm[sel], np.exp(np.polyval(np.polyfit(np.log(qm[sel]), np.log(Pm[sel]), 1), np.log(qm[sel]))),
          "r-", label=f"fit slope {slope:.3f} (target {-2*(1+H):.3f})")
ax.axvline(qL, color="k", ls=":"); ax.axvline(qS, color="k", ls=":")
ax.set_xlabel("q (1/m)"); ax.set_ylabel("PSD (arb.)"); ax.legend()
fig.tight_layout(); fig.savefig(out("psd.png"), dpi=110); plt.close(fig)
lines.append(f"- road: {z.shape[1]}×{z.shape[0]} points at {dx*1e6:.0f} µm, rms {z.std()*1e6:.2f} µm "
             f"(requested 100), PSD slope {slope:.3f} vs −2(1+H) = {-2*(1+H):.3f} "
             f"({abs(slope/(-2*(1+H))-1)*100:.2f} %)")

# ------------------------------------------------------------------ springs
def herm(x, y, m, t):
    t = np.asarray(t); res = np.empty_like(t); der = np.empty_like(t)
    for n, tt in enumerate(t):
        if tt >= x[-1]:
            res[n] = y[-1] + m[-1] * (tt - x[-1]); der[n] = m[-1]; continue
        i = min(max(np.searchsorted(x, tt) - 1, 0), len(x) - 2)
        h = x[i + 1] - x[i]; s = (tt - x[i]) / h
        res[n] = ((2*s**3 - 3*s**2 + 1) * y[i] + (s**3 - 2*s**2 + s) * h * m[i]
                  + (-2*s**3 + 3*s**2) * y[i+1] + (s**3 - s**2) * h * m[i+1])
        der[n] = ((6*s**2 - 6*s) * y[i] + (3*s**2 - 4*s + 1) * h * m[i]
                  + (-6*s**2 + 6*s) * y[i+1] + (3*s**2 - 2*s) * h * m[i+1]) / h
    return res, der

order = np.argsort(F[:, -1])
pick = [order[int(p * (len(order) - 1))] for p in (0.1, 0.4, 0.7, 0.95)]
fig, ax = plt.subplots(2, 4, figsize=(15, 7))
for c, e in enumerate(pick):
    t = rd[e]
    fh, kh = herm(d[e], F[e], k[e], t)
    cp = poly[e]
    fp = np.polyval(cp[::-1], t)
    kp = np.polyval((cp[1:] * np.arange(1, 11))[::-1], t)
    ax[0, c].plot(t * 1e6, rF[e], "k-", lw=2.5, alpha=.35, label="raw (Yang punch sum)")
    ax[0, c].plot(t * 1e6, fh, "b-", label=f"Hermite, err {eh[e]*100:.2f} %")
    ax[0, c].plot(t * 1e6, fp, "r--", label=f"10th-order poly, err {ep[e]*100:.2f} %")
    ax[0, c].plot(d[e] * 1e6, F[e], "b.", ms=4)
    ax[0, c].set_title(f"element {e} ({e%20}, {e//20})"); ax[0, c].legend(fontsize=7)
    ax[0, c].set_ylabel("F (N)")
    ax[1, c].plot(t * 1e6, rk[e] / 1e3, "k-", lw=2.5, alpha=.35, label="raw dF/dd")
    ax[1, c].plot(t * 1e6, kh / 1e3, "b-", label="Hermite")
    ax[1, c].plot(t * 1e6, kp / 1e3, "r--", label="poly")
    ax[1, c].set_xlabel("compression d (µm)"); ax[1, c].set_ylabel("k (kN/m)")
    ax[1, c].legend(fontsize=7)
fig.suptitle(f"roughness springs (cf. seed 002 fig. 12); film: {rule}")
fig.tight_layout(); fig.savefig(out("springs.png"), dpi=100); plt.close(fig)

# adhesion branch of one element
e = pick[1]
dd = np.linspace(-d[e, -1] * 0.3, d[e, -1] * 0.3, 400)
fa = []
att = 1
for x in dd[::-1]:  # unloading from compression into tension
    if x >= 0:
        att = 1; fa.append(herm(d[e], F[e], k[e], [x])[0][0])
    elif att:
        f_ = -herm(d[e], F[e], k[e], [-x])[0][0]
        if -f_ > rel:
            att = 0; f_ = 0
        fa.append(f_)
    else:
        fa.append(0)
fig, ax = plt.subplots(figsize=(6, 4.2))
ax.plot(dd[::-1] * 1e6, fa, "b-")
ax.axhline(-rel, color="r", ls=":", label=f"release force {rel} N")
ax.set_xlabel("d (µm)"); ax.set_ylabel("F (N)"); ax.legend()
ax.set_title(f"element {e}: mirrored branch and release on unloading (seed 002 fig. 13)")
fig.tight_layout(); fig.savefig(out("adhesion.png"), dpi=110); plt.close(fig)
lines.append(f"- springs: {len(F)} elements, {d.shape[1]} knots, film rule '{rule}'; F at the last knot "
             f"{F[:,-1].min():.3g}–{F[:,-1].max():.3g} N (median {np.median(F[:,-1]):.3g}), "
             f"d_max {d[:,-1].min()*1e6:.1f}–{d[:,-1].max()*1e6:.1f} µm")
lines.append(f"- fit error vs the raw curve (max over depths, of F(d_max)): Hermite median "
             f"{np.median(eh)*100:.3f} %, worst {eh.max()*100:.2f} %; polynomial median "
             f"{np.median(ep)*100:.3f} %, worst {ep.max()*100:.2f} %")
kmin = np.min(k); lines.append(f"- Hermite slopes all ≥ 0: {bool(kmin >= 0)}; "
                               f"k at d = 0: median {np.median(k[:,0]):.3g} N/m")

# ------------------------------------------------------------------ punch
p = np.loadtxt(os.path.join(T, "punch.txt"))
fig, ax = plt.subplots(figsize=(6, 4.4))
ax.loglog(p[:, 0], p[:, 1], "b.-", label="Nyström solve, ν = 0.5")
ax.loglog(p[:, 0], p[:, 4], "g.-", label="ν = 0.45")
ax.loglog(p[:, 0], p[:, 2], "k:", label="half-space 2E*a")
ax.loglog(p[:, 0], p[:, 3], "r--", label="thin film (3π/8) G a⁴/h³")
ax.set_ylim(0.8, p[:, 1].max() * 2)
ax.set_xlabel("a/h"); ax.set_ylabel("K / (2E*a)"); ax.legend()
ax.set_title("flat punch on a bonded film (frictionless face)")
fig.tight_layout(); fig.savefig(out("punch.png"), dpi=110); plt.close(fig)

# ------------------------------------------------------------------ green
def load(n):
    with h5py.File(os.path.join(T, n)) as f:
        g = f["green"]
        return ({a: g.attrs[a] for a in g.attrs}, g["g"][:] if "g" in g else None, g["static"][:],
                g["static_relaxed"][:] if "static_relaxed" in g else None)

try:
    az, gz, sz, srel = load("green.h5")
    ap, gp, sp, _ = load("green_point.h5")
    nx = int(az["nx"]); ny = int(az["ny"]); rate = az["rate"]
    c = (ny - 1, nx - 1)
    offs = [(0, 0), (1, 0), (1, 1), (2, 0), (3, 0)]
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.4))
    for (i, j) in offs:
        l, = ax[0].plot(range(13), gz[:13, c[0] + j, c[1] + i], "o-", ms=4, label=f"offset ({i},{j}) zoh")
        ax[0].plot(range(13), gp[:13, c[0] + j, c[1] + i], "x--", color=l.get_color(), ms=5)
    ax[0].set_xlabel("sample k"); ax[0].set_ylabel("g (m/(N s))")
    ax[0].set_title("first 13 samples (cf. seed 002 fig. 15); o zoh, x point"); ax[0].legend(fontsize=8)
    t = np.arange(1, gz.shape[0] + 1) / rate
    for (i, j) in offs[:3]:
        l, = ax[1].plot(t * 1e3, np.cumsum(gz[:, c[0] + j, c[1] + i]) / rate * 1e6, label=f"({i},{j}) Δt Σ zoh")
        ax[1].plot(t * 1e3, np.cumsum(gp[:, c[0] + j, c[1] + i]) / rate * 1e6, "--", color=l.get_color())
        ax[1].axhline(srel[c[0] + j, c[1] + i] * 1e6, color=l.get_color(), ls=":")
    ax[1].set_xlabel("t (ms)"); ax[1].set_ylabel("step response (µm/N)")
    ax[1].set_title("running sums (— zoh, -- point, ··· static layer)"); ax[1].legend(fontsize=8)
    fig.tight_layout(); fig.savefig(out("green.png"), dpi=110); plt.close(fig)
    sc = c
    lines.append(f"- dynamic Green's functions 20×20, Q = {gz.shape[0]} at {rate:.0f} Hz, appendix-B table: "
                 f"g_zoh(0) self {gz[0, sc[0], sc[1]]:.4g}, point {gp[0, sc[0], sc[1]]:.4g} m/(N s); "
                 f"static self {srel[sc]:.4g} m/N; time-sum check (zoh) {az['sum_check']*100:.2f} %, "
                 f"point samples {np.max(np.abs(sp - srel))/srel[sc]*100:.1f} %")
    for n, what in (("green_4.h5", "4×4, Q = 256, auto box"), ("green_q1024.h5", "4×4, Q = 1024"),
                    ("green_pad120.h5", "4×4, Q = 256, box padded by 120 elements")):
        a4, g4, s4, r4 = load(n)
        cc = (int(a4["ny"]) - 1, int(a4["nx"]) - 1)
        lines.append(f"  - {what}: sum check {a4['sum_check']*100:.2f} %, g_zoh(0..2) self "
                     f"{g4[0,cc[0],cc[1]]:.4g} {g4[1,cc[0],cc[1]]:.4g} {g4[2,cc[0],cc[1]]:.4g}")
except (OSError, KeyError) as ex:
    lines.append(f"- dynamic Green's functions: not available ({ex})")

with h5py.File(os.path.join(T, "layer.h5")) as f:
    lay = f["green/static"][:]
with h5py.File(os.path.join(T, "love.h5")) as f:
    lov = f["green/static"][:]
fig, ax = plt.subplots(figsize=(6, 4.4))
x = np.arange(-19, 20)
ax.semilogy(x, lov[19], "k.-", label="half-space (Love)")
ax.semilogy(x, np.abs(lay[19]), "b.-", label="layer h = 10 mm, rigid base")
ax.set_xlabel("offset Δi (elements)"); ax.set_ylabel("static compliance (m/N)")
ax.legend(); ax.set_title("quasi-static influence coefficients, E = 25 MPa")
fig.tight_layout(); fig.savefig(out("static.png"), dpi=110); plt.close(fig)
lines.append(f"- static self coefficient: Love {lov[19,19]:.4g} m/N, layer (10 mm) {lay[19,19]:.4g} m/N; "
             f"at offset 19: Love {lov[19,38]:.3g}, layer {lay[19,38]:.3g}")
open(os.path.join(T, "numbers.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
