#!/usr/bin/python3
"""docs/python.md's example, cell by cell: error against time on the Cornell box, drawn with
matplotlib into docs/python-error-vs-time.png. Run from the source tree after `make`:

    /usr/bin/python3 docs/python-example.py [WORKDIR]

Each "# %%" is a notebook cell (Jupyter, VS Code and Spyder run them one by one)."""

# %% Set-up: the package is the tree's python/pmtk; the programs its bin/.
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import pmtk

work = sys.argv[1] if len(sys.argv) > 1 else "out/python-example"
scene = "scenes/cornell-box/scene.json"
size = dict(WIDTH=64, HEIGHT=48)
os.makedirs(work, exist_ok=True)

# %% A reference: the path tracer, 1024 paths a pixel, with each pixel's variance.
ref = os.path.join(work, "reference.pm")
if not os.path.exists(ref):
    pmtk.run("trace-reference", scene, "--width", 64, "--height", 48, "--spp", 1024, "--pass", 256,
             "--radiance", ref, "-o", os.path.join(work, "reference.exr"))
r = pmtk.read(ref)
print(r.header["samples"], "paths a pixel; mean radiance", r.records["rgb"].mean(axis=0))
print("the reference's own relative error:", np.sqrt(r.records["variance"] / np.maximum(r.records["rgb"], 1e-3) ** 2).mean())

# %% The photon pipeline at growing photon counts: its time, and its error against the reference.
rows = []
for photons in (5000, 20000, 80000, 320000):
    out = os.path.join(work, "photons-%d" % photons)
    stats = pmtk.render(scene, out, PHOTONS=photons, SPP=8, KEEP="buffers", **size)
    # the image as a radiance buffer: the direct and indirect buffers summed by composite
    total = os.path.join(out, "total.pm")
    pmtk.run("composite", os.path.join(out, "direct.pm"), os.path.join(out, "indirect.pm"), "--radiance", total,
             "-o", os.path.join(out, "check.exr"))
    err = pmtk.measure_error(total, ref)
    rows.append((photons, stats["python_seconds"], err["relmse"]))
    print("%7d photons: %.2f s, relative MSE %.4g" % rows[-1])

# %% The path tracer's own curve: the same scene at growing paths a pixel.
pt = []
for spp in (4, 16, 64):
    path = os.path.join(work, "pt-%d.pm" % spp)
    t0 = time.perf_counter()
    pmtk.run("trace-reference", scene, "--width", 64, "--height", 48, "--spp", spp, "--pass", spp, "--seed", 7,
             "--radiance", path, "-o", os.path.join(work, "pt-%d.exr" % spp))
    pt.append((spp, time.perf_counter() - t0, pmtk.measure_error(path, ref)["relmse"]))
    print("%4d paths a pixel: %.2f s, relative MSE %.4g" % pt[-1])

# %% The plot: log-log relative MSE against seconds.
fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
ax.loglog([t for _, t, _ in rows], [e for _, _, e in rows], "o-", label="photon mapping (pm-render)")
for n, t, e in rows:
    ax.annotate("%dk" % (n // 1000), (t, e), textcoords="offset points", xytext=(4, 4), fontsize=8)
ax.loglog([t for _, t, _ in pt], [e for _, _, e in pt], "s--", label="path tracing (trace-reference)")
for n, t, e in pt:
    ax.annotate("%d spp" % n, (t, e), textcoords="offset points", xytext=(4, -10), fontsize=8)
ax.set_xlabel("wall time, s (whole render from nothing)")
ax.set_ylabel("relative MSE against a 1024-spp reference")
ax.set_title("Cornell box, 64 x 48")
ax.grid(True, which="both", alpha=0.3)
ax.legend()
fig.tight_layout()
png = os.path.join(os.path.dirname(os.path.abspath(__file__)), "python-error-vs-time.png")
fig.savefig(png)
print("wrote", png)
