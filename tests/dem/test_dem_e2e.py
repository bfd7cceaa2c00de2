"""dem_server end to end: the coupler runs it against fem_stub (a flat tread
surface pressed into a small settled bed). Checks the series, the snapshots,
and that the force the grains put on the surface (wall_forces of the surface
wall) is what the FEM side received (its vertical load), step by step."""
import os, subprocess, sys, tempfile
import h5py, numpy as np

here = os.path.dirname(os.path.abspath(__file__))
cosim = os.path.join(os.environ["COSIM_BIN"], "cosim")
with tempfile.TemporaryDirectory() as tmp:
    r = subprocess.run([cosim, "run", os.path.join(here, "e2e_dem_surface.json")], cwd=tmp,
                       capture_output=True, text=True, timeout=240)
    print(r.stdout[-2000:], r.stderr[-2000:])
    assert r.returncode == 0, "cosim run failed"
    f = h5py.File(os.path.join(tmp, "runs/dem_surface_e2e/results.h5"))
    s = f["dem/series"]
    cols = [c.decode() if isinstance(c, bytes) else c for c in s.attrs["columns"]]
    assert cols[:4] == ["t", "kinetic_energy", "contacts", "max_overlap_ratio"], cols
    assert s.shape[0] == 150, s.shape
    assert np.all(np.isfinite(s[:])), "non-finite series"
    n = f["dem/steps/50/x"].shape[0]
    for a, shape in (("x", (n, 3)), ("v", (n, 3)), ("omega", (n, 3)), ("r", (n,))):
        assert f["dem/steps/150/" + a].shape == shape, a
    assert np.all(f["dem/steps/150/r"][:] > 0)
    w = f["dem/wall_forces"][:]
    tr = f["coupler/traction"]
    tcols = [c.decode() if isinstance(c, bytes) else c for c in tr.attrs["columns"]]
    load = tr[:, tcols.index("vertical_load")]
    # wall 1 is the FEM surface; its z force is the load the tread carries
    assert np.max(np.abs(w[:, 6])) > 0.1, "the surface never touched the bed"
    err = np.max(np.abs(w[:, 6] - load)) / np.max(np.abs(load))
    print("max |surface Fz - coupler vertical load| / max load = %.3g" % err)
    assert err < 1e-12, err
    print("ok")
