"""pmtk in Python: every pmtk file as numpy, and the programs and pipelines as functions.

    import pmtk
    m = pmtk.read("out/cornell/photonmap.pm")   # m.header (dict), m.records (numpy, mmap)
    m.records["power"].sum(axis=0)               # watts stored, RGB
    pmtk.write("copy.pm", m)                     # the same bytes
    stats = pmtk.render("scenes/cornell-box/scene.json", "out/c", PHOTONS=100000)

Pure Python over numpy and xxhash (Debian's python3-numpy and python3-xxhash); docs/python.md
is the guide and docs/formats.md the byte-level spec it follows. Where libpmtk.so is present
(the C library of issue 31), ``lib()`` loads it through ctypes; without it every reading and
writing function works and ``lib()`` returns None.
"""

import ctypes
import ctypes.util
import json
import os
import shutil
import subprocess
import time

from .formats import FormatError, PmFile, SCHEMAS, check_records, dtype, empty, read, read_stream, write

__all__ = ["FormatError", "PmFile", "SCHEMAS", "RunError", "check_records", "dtype", "empty", "read", "read_stream",
           "write", "bin_dir", "run", "render", "measure_error", "lib", "native"]
__version__ = "0.1.0"

_HERE = os.path.dirname(os.path.abspath(__file__))
_TREE = os.path.dirname(os.path.dirname(_HERE))  # python/pmtk -> the source tree

# docs/cli.md: the exit status is the class of the failure.
EXIT_CLASSES = {1: "input", 2: "usage", 3: "system", 4: "internal"}


class RunError(RuntimeError):
    """A pmtk program that exited non-zero: .status (its exit code), .klass (input, usage,
    system or internal, docs/cli.md), .stderr, .argv; str() is the program's own message."""

    def __init__(self, argv, status, stderr):
        self.argv, self.status, self.stderr = argv, status, stderr
        self.klass = EXIT_CLASSES.get(status, "signal" if status < 0 else "unknown")
        lines = [ln for ln in stderr.splitlines() if ln.strip()]
        super().__init__("%s (exit %d, %s)" % (lines[-1] if lines else os.path.basename(argv[0]), status, self.klass))

    @property
    def retryable(self):
        return self.status == 3


def bin_dir():
    """Where the programs are: $PMTK_BIN, else the source tree's bin/ when this package is
    the tree's python/pmtk, else the directory of trace-photons on PATH."""
    env = os.environ.get("PMTK_BIN")
    if env:
        return env
    tree = os.path.join(_TREE, "bin")
    if os.path.isfile(os.path.join(tree, "trace-photons")):
        return tree
    found = shutil.which("trace-photons")
    if found:
        return os.path.dirname(found)
    raise FileNotFoundError("pmtk programs not found: build them (make) or set PMTK_BIN")


def run(program, *args, stdin=None, cwd=None, quiet=True):
    """Runs one pmtk program with args (each converted with str) and returns its stdout as
    bytes; a non-zero exit raises RunError carrying the program's message and class.
    quiet adds -q so that warnings do not fill stderr."""
    argv = [os.path.join(bin_dir(), program)] + (["-q"] if quiet and program != "pm-render" else []) + [str(a) for a in args]
    p = subprocess.run(argv, input=stdin, capture_output=True, cwd=cwd)
    if p.returncode != 0:
        raise RunError(argv, p.returncode, p.stderr.decode("utf-8", "replace"))
    return p.stdout


def render(scene, outdir, *targets, **settings):
    """Renders scene into outdir with pm-render (pipelines/render), reusing what the
    settings allow, and returns its stats.json as a dict with the wall time it took here
    under 'python_seconds'. settings are pm-render's NAME=VALUE words (PHOTONS=100000,
    PASSES=4, TIME=10, ...); targets its TARGET words."""
    words = ["%s=%s" % (k, v) for k, v in settings.items()]
    t0 = time.perf_counter()
    run("pm-render", scene, outdir, *words, *targets, quiet=False)
    took = time.perf_counter() - t0
    stats = {}
    path = os.path.join(outdir, "stats.json")
    if os.path.exists(path):
        with open(path) as f:
            stats = json.load(f)
    stats["python_seconds"] = took
    return stats


def measure_error(test, reference):
    """measure-error's JSON for a test image against a reference (radiance buffers or EXR)."""
    return json.loads(run("measure-error", test, reference).decode())


_LIB = None


def lib(path=None):
    """The C library libpmtk.so through ctypes, or None when it is not installed or built:
    $PMTK_LIB, then the tree's build (build/lib), then the system's (ldconfig). The API is
    include/pmtk.h's; native() wraps it for numpy arrays (pmtk/native.py)."""
    global _LIB
    if _LIB is not None and path is None:
        return _LIB
    candidates = [path] if path else [os.environ.get("PMTK_LIB")]
    if not path:
        for d in ("build/lib", "build", "lib"):
            full = os.path.join(_TREE, d)
            if os.path.isdir(full):
                candidates += sorted(os.path.join(full, n) for n in os.listdir(full) if n.startswith("libpmtk.so"))
        candidates.append(ctypes.util.find_library("pmtk"))
    for c in candidates:
        if not c:
            continue
        try:
            handle = ctypes.CDLL(c)
        except OSError:
            continue
        if path is None:
            _LIB = handle
        return handle
    return None


def native(threads=0, path=None):
    """A pmtk.native.Native over libpmtk (the packet gather, k-NN and Hilbert order on numpy
    arrays), or None when the library is not there."""
    handle = lib(path)
    if handle is None:
        return None
    from .native import Native

    return Native(handle, threads)
