"""libpmtk through ctypes: the paper's packet gather, the k-NN baseline and Hilbert order on numpy
arrays (include/pmtk.h, API version 1). pmtk.lib() finds the library; Native wraps it:

    nat = pmtk.native()                  # None when libpmtk.so is not built or installed
    m = nat.build_map(position, power, normal)          # or nat.read_map("photonmap.pm")
    E, stats = nat.gather(m, qpos, qnormal, radius=0.05)  # (n, 3) float64, W/m^2

Every array is converted to contiguous float32 (n, 3) as the C API wants; a failure raises
LibError with the library's own message and result code."""

import ctypes as C

import numpy as np

KERNELS = {"uniform": 0, "epanechnikov": 1}
ISAS = {"auto": -1, "scalar": 0, "sse4": 1, "avx2": 2, "avx512": 3}


class LibError(RuntimeError):
    """A libpmtk call that failed: .code (PMTK_ERR_*), str() the library's message."""

    def __init__(self, code, message):
        self.code = code
        super().__init__(message)


class _Photons(C.Structure):
    _fields_ = [("count", C.c_uint64), ("position", C.c_void_p), ("power", C.c_void_p), ("normal", C.c_void_p),
                ("direction", C.c_void_p)]


class _Queries(C.Structure):
    _fields_ = [("count", C.c_uint64), ("position", C.c_void_p), ("normal", C.c_void_p), ("radius", C.c_void_p)]


class _GatherParams(C.Structure):
    _fields_ = [("radius", C.c_double), ("kernel", C.c_int), ("normal_cos", C.c_float), ("isa", C.c_int)]


class _GatherStats(C.Structure):
    _fields_ = [("shader_ops", C.c_uint64), ("nodes_visited", C.c_uint64), ("packets", C.c_uint64),
                ("packet_width", C.c_int), ("cpu_s", C.c_double)]


class _KnnParams(C.Structure):
    _fields_ = [("k", C.c_uint32), ("max_radius", C.c_double), ("kernel", C.c_int), ("normal_cos", C.c_float)]


def _vec3(a, n=None, name="array"):
    a = np.ascontiguousarray(a, dtype=np.float32)
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and len(a) != n):
        raise ValueError("%s: expected shape (%s, 3), got %s" % (name, n if n is not None else "n", a.shape))
    return a


def _ptr(a):
    return None if a is None else a.ctypes.data_as(C.c_void_p)


class PhotonMap:
    """A photon map held by the library (pmtk_photonmap_t), freed with the object."""

    def __init__(self, native, handle):
        self._native, self._h = native, handle

    def __len__(self):
        return self._native._lib.pmtk_photonmap_count(self._h)

    def write(self, path):
        self._native._check(self._native._lib.pmtk_photonmap_write(self._native._ctx, self._h, path.encode()))

    def __del__(self):
        if getattr(self, "_h", None):
            self._native._lib.pmtk_photonmap_destroy(self._h)
            self._h = None


class Native:
    """One pmtk_context_t over the loaded library (a CDLL from pmtk.lib())."""

    def __init__(self, lib, threads=0):
        self._lib = L = lib
        vp, res = C.c_void_p, C.c_int32
        for name, args, ret in (
                ("pmtk_context_create", [C.POINTER(vp)], res), ("pmtk_context_destroy", [vp], None),
                ("pmtk_context_set_threads", [vp, C.c_int], res), ("pmtk_context_error", [vp], C.c_char_p),
                ("pmtk_version", [], C.c_char_p),
                ("pmtk_photonmap_build", [vp, C.POINTER(_Photons), C.POINTER(vp)], res),
                ("pmtk_photonmap_read", [vp, C.c_char_p, C.POINTER(vp)], res),
                ("pmtk_photonmap_write", [vp, vp, C.c_char_p], res),
                ("pmtk_photonmap_count", [vp], C.c_uint64), ("pmtk_photonmap_destroy", [vp], None),
                ("pmtk_gather_params_init", [C.POINTER(_GatherParams)], None),
                ("pmtk_gather", [vp, vp, C.POINTER(_Queries), C.POINTER(_GatherParams), vp, C.POINTER(_GatherStats)], res),
                ("pmtk_knn_gather", [vp, vp, C.POINTER(_Queries), C.POINTER(_KnnParams), vp], res),
                ("pmtk_hilbert_order", [vp, vp, C.c_size_t, C.c_uint64, C.c_uint64, vp], res)):
            f = getattr(L, name)
            f.argtypes, f.restype = args, ret
        self._ctx = vp()
        self._check(L.pmtk_context_create(C.byref(self._ctx)), "pmtk_context_create")
        if threads:
            self._check(L.pmtk_context_set_threads(self._ctx, int(threads)))

    @property
    def version(self):
        return self._lib.pmtk_version().decode()

    def _check(self, code, what=None):
        if code != 0:
            msg = self._lib.pmtk_context_error(self._ctx) if self._ctx else None
            raise LibError(code, (msg.decode("utf-8", "replace") if msg else what or "libpmtk error %d" % code))

    def __del__(self):
        if getattr(self, "_ctx", None):
            self._lib.pmtk_context_destroy(self._ctx)
            self._ctx = None

    def build_map(self, position, power, normal, direction=None):
        """The paper's KD-tree over n photons: position, power (W, RGB), normal and optionally
        direction, each (n, 3)."""
        pos = _vec3(position, None, "position")
        n = len(pos)
        pw, nm = _vec3(power, n, "power"), _vec3(normal, n, "normal")
        d = None if direction is None else _vec3(direction, n, "direction")
        ph = _Photons(n, _ptr(pos), _ptr(pw), _ptr(nm), _ptr(d))
        h = C.c_void_p()
        self._check(self._lib.pmtk_photonmap_build(self._ctx, C.byref(ph), C.byref(h)))
        return PhotonMap(self, h)

    def read_map(self, path):
        """A photon map file (build-photonmap's), read and checked by the library."""
        h = C.c_void_p()
        self._check(self._lib.pmtk_photonmap_read(self._ctx, str(path).encode(), C.byref(h)))
        return PhotonMap(self, h)

    def _queries(self, position, normal, radius=None):
        pos = _vec3(position, None, "query position")
        nm = _vec3(normal, len(pos), "query normal")
        r = None
        if radius is not None and np.ndim(radius) > 0:
            r = np.ascontiguousarray(radius, dtype=np.float32)
            if r.shape != (len(pos),):
                raise ValueError("radius: expected shape (%d,), got %s" % (len(pos), r.shape))
        return _Queries(len(pos), _ptr(pos), _ptr(nm), _ptr(r)), (pos, nm, r)

    def gather(self, photon_map, position, normal, radius, kernel="uniform", normal_cos=0.0, isa="auto"):
        """The sample-point estimator at n queries (position, normal (n, 3)); radius one width in
        m or an array of n. Returns (out, stats): out (n, 3) float64 in W/m^2, stats a dict."""
        q, keep = self._queries(position, normal, radius)
        p = _GatherParams()
        self._lib.pmtk_gather_params_init(C.byref(p))
        p.radius = 0.0 if np.ndim(radius) > 0 else float(radius)
        p.kernel, p.normal_cos, p.isa = KERNELS[kernel], float(normal_cos), ISAS[isa]
        out = np.zeros((q.count, 3), dtype=np.float64)
        st = _GatherStats()
        self._check(self._lib.pmtk_gather(self._ctx, photon_map._h, C.byref(q), C.byref(p), _ptr(out), C.byref(st)))
        del keep
        return out, {k: getattr(st, k) for k, _ in _GatherStats._fields_}

    def knn_gather(self, photon_map, position, normal, k, max_radius=0.0, kernel="uniform", normal_cos=0.0):
        """The k-nearest-photons baseline at the queries: (n, 3) float64."""
        q, keep = self._queries(position, normal)
        p = _KnnParams(int(k), float(max_radius), KERNELS[kernel], float(normal_cos))
        out = np.zeros((q.count, 3), dtype=np.float64)
        self._check(self._lib.pmtk_knn_gather(self._ctx, photon_map._h, C.byref(q), C.byref(p), _ptr(out)))
        del keep
        return out

    def hilbert_order(self, position, leaf=1):
        """The permutation that puts points (n, 3) in 3-D Hilbert order (uint32 indices)."""
        pos = _vec3(position, None, "position")
        perm = np.zeros(len(pos), dtype=np.uint32)
        self._check(self._lib.pmtk_hilbert_order(self._ctx, _ptr(pos), 12, len(pos), int(leaf), _ptr(perm)))
        return perm
