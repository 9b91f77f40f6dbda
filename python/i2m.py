"""i2m from Python: mesh a segmented 3D image held in a numpy array.

ctypes over libi2m.so (nothing to compile); numpy in, numpy (and a meshio.Mesh) out.

    import numpy as np, i2m
    labels = ...                       # 3D integer array, 0 = background
    m = i2m.mesh(labels, spacing=(0.5, 0.5, 1.0), delta=1.0)   # a meshio.Mesh
    m.points, m.cells_dict["tetra"], m.cell_data["material"]

    # SimpleITK: i2m.mesh_sitk(sitk.ReadImage("seg.nrrd"))
    # nibabel:   i2m.mesh_nibabel(nibabel.load("seg.nii.gz"))

Array order: by default `labels[k, j, i]` (axes="zyx": what SimpleITK's GetArrayFromImage gives,
the first index the slice); axes="xyz" for `labels[i, j, k]` (nibabel's get_fdata order).
Spacing, origin and direction are given along i, j, k (x, y, z) in world LPS coordinates (mm),
as in the image file; direction is 3x3 with column c the world direction of index axis c.

The library is found at $I2M_LIBRARY, else beside this file (../lib of a source tree, or the
lib of an installation prefix), else on the system's library path.
"""
import ctypes
import ctypes.util
import os

import numpy as np

__all__ = ["mesh", "mesh_arrays", "mesh_sitk", "mesh_nibabel", "I2MError"]


class I2MError(RuntimeError):
    """A failed call: the library's one-line message."""


class _Options(ctypes.Structure):
    _fields_ = [("delta", ctypes.c_double), ("ratio", ctypes.c_double), ("facet_angle", ctypes.c_double),
                ("size", ctypes.c_double), ("nlabel_sizes", ctypes.c_int),
                ("label_size_values", ctypes.POINTER(ctypes.c_int64)), ("label_sizes", ctypes.POINTER(ctypes.c_double)),
                ("nregions", ctypes.c_int), ("regions", ctypes.POINTER(ctypes.c_double)),
                ("sliver_angle", ctypes.c_double), ("threads", ctypes.c_int), ("deterministic", ctypes.c_int),
                ("depth", ctypes.c_int), ("coarse_factor", ctypes.c_double), ("pin", ctypes.c_int), ("check", ctypes.c_int),
                ("seed", ctypes.c_uint64), ("max_memory", ctypes.c_double), ("verbose", ctypes.c_int)]


class _Mesh(ctypes.Structure):
    _fields_ = [("npoints", ctypes.c_int64), ("points", ctypes.POINTER(ctypes.c_double)),
                ("ntets", ctypes.c_int64), ("tets", ctypes.POINTER(ctypes.c_int32)),
                ("materials", ctypes.POINTER(ctypes.c_int64)),
                ("ntriangles", ctypes.c_int64), ("triangles", ctypes.POINTER(ctypes.c_int32)),
                ("triangle_labels", ctypes.POINTER(ctypes.c_int64))]


# numpy dtype -> i2m_label_type_t (include/i2m.h)
_TYPES = {np.dtype(np.uint8): 1, np.dtype(np.int8): 2, np.dtype(np.uint16): 3, np.dtype(np.int16): 4,
          np.dtype(np.uint32): 5, np.dtype(np.int32): 6, np.dtype(np.int64): 7}

_lib = None


def _library():
    global _lib
    if _lib is not None:
        return _lib
    here = os.path.dirname(os.path.abspath(__file__))
    candidates = [os.environ.get("I2M_LIBRARY"),
                  os.path.join(here, "..", "lib", "libi2m.so"),              # a source tree
                  os.path.join(here, "..", "..", "..", "lib", "libi2m.so"),  # PREFIX/share/i2m/python
                  ctypes.util.find_library("i2m")]
    for c in candidates:
        if c and (os.path.exists(c) or not os.path.isabs(c)):
            try:
                lib = ctypes.CDLL(c)
                break
            except OSError:
                continue
    else:
        raise I2MError("libi2m.so not found: build it (make), or set I2M_LIBRARY to its path")
    lib.i2m_options_init.argtypes = [ctypes.POINTER(_Options)]
    lib.i2m_options_init.restype = None
    lib.i2m_mesh_labels.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_int64),
                                    ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                                    ctypes.POINTER(ctypes.c_double), ctypes.POINTER(_Options),
                                    ctypes.POINTER(ctypes.POINTER(_Mesh))]
    lib.i2m_mesh_labels.restype = ctypes.c_int
    lib.i2m_mesh_free.argtypes = [ctypes.POINTER(ctypes.POINTER(_Mesh))]
    lib.i2m_mesh_free.restype = None
    lib.i2m_last_error.argtypes = []
    lib.i2m_last_error.restype = ctypes.c_char_p
    _lib = lib
    return lib


def _doubles(values, n, what):
    a = np.ascontiguousarray(np.asarray(values, dtype=np.float64).reshape(-1))
    if a.size != n:
        raise ValueError("%s needs %d numbers" % (what, n))
    return a


def _options(lib, opts):
    o = _Options()
    lib.i2m_options_init(ctypes.byref(o))
    keep = []
    for key, value in opts.items():
        if key == "size_labels":  # {label: size}
            values = np.ascontiguousarray(np.array(list(value.keys()), dtype=np.int64))
            sizes = np.ascontiguousarray(np.array(list(value.values()), dtype=np.float64))
            keep += [values, sizes]
            o.nlabel_sizes = len(values)
            o.label_size_values = values.ctypes.data_as(ctypes.POINTER(ctypes.c_int64))
            o.label_sizes = sizes.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        elif key == "regions":  # [(x0, y0, z0, x1, y1, z1, size[, ratio]), ...]
            rows = [list(map(float, r)) + [0.0] * (8 - len(r)) for r in value]
            if any(len(r) != 8 for r in rows):
                raise ValueError("a region is (x0, y0, z0, x1, y1, z1, size[, ratio])")
            regions = np.ascontiguousarray(np.array(rows, dtype=np.float64).reshape(-1))
            keep.append(regions)
            o.nregions = len(rows)
            o.regions = regions.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        elif key in ("deterministic", "verbose", "threads", "depth", "pin", "check"):
            setattr(o, key, int(value))
        elif key in ("delta", "ratio", "facet_angle", "size", "sliver_angle", "max_memory", "seed", "coarse_factor"):
            setattr(o, key, value)
        else:
            raise TypeError("unknown i2m option %r" % key)
    return o, keep


def mesh_arrays(labels, spacing=(1.0, 1.0, 1.0), origin=None, direction=None, axes="zyx", **opts):
    """Meshes `labels`; returns (points [P,3], tets [T,4], materials [T], triangles [F,3],
    triangle_labels [F,2]) as numpy arrays.  Options (those of the command line): delta, ratio,
    facet_angle, size, size_labels={label: size}, regions=[(x0, y0, z0, x1, y1, z1, size[, ratio])],
    sliver_angle, threads, deterministic, depth, coarse_factor, pin, check, seed, max_memory,
    verbose (0 silent, 1 progress, 2 debug)."""
    lib = _library()
    a = np.asarray(labels)
    if a.ndim != 3:
        raise ValueError("labels must be a 3D array, not %dD" % a.ndim)
    if axes == "xyz":
        a = a.transpose(2, 1, 0)
    elif axes != "zyx":
        raise ValueError('axes must be "zyx" (labels[k, j, i]) or "xyz" (labels[i, j, k])')
    if a.dtype not in _TYPES:
        if a.dtype.kind not in "iub":
            raise TypeError("labels must be integers, not %s" % a.dtype)
        a = a.astype(np.int64)
    a = np.ascontiguousarray(a)  # memory: i fastest
    dims = np.array(a.shape[::-1], dtype=np.int64)
    sp = _doubles(spacing, 3, "spacing")
    org = None if origin is None else _doubles(origin, 3, "origin")
    # direction[r][c] (row-major): world component r of index axis c
    dirs = None if direction is None else _doubles(np.asarray(direction, dtype=np.float64).reshape(3, 3), 9, "direction")
    o, keep = _options(lib, opts)
    dp = ctypes.POINTER(ctypes.c_double)
    out = ctypes.POINTER(_Mesh)()
    rc = lib.i2m_mesh_labels(a.ctypes.data_as(ctypes.c_void_p), _TYPES[a.dtype],
                             dims.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), sp.ctypes.data_as(dp),
                             None if org is None else org.ctypes.data_as(dp),
                             None if dirs is None else dirs.ctypes.data_as(dp), ctypes.byref(o), ctypes.byref(out))
    del keep
    if rc != 0:
        raise I2MError(lib.i2m_last_error().decode("utf-8", "replace"))
    try:
        m = out.contents
        def take(ptr, n, width, dtype):
            if n == 0:
                return np.zeros((0, width) if width > 1 else 0, dtype=dtype)
            x = np.ctypeslib.as_array(ptr, shape=(n * width,)).copy()
            return x.reshape(n, width) if width > 1 else x
        return (take(m.points, m.npoints, 3, np.float64), take(m.tets, m.ntets, 4, np.int32),
                take(m.materials, m.ntets, 1, np.int64), take(m.triangles, m.ntriangles, 3, np.int32),
                take(m.triangle_labels, m.ntriangles, 2, np.int64))
    finally:
        lib.i2m_mesh_free(ctypes.byref(out))


def mesh(labels, spacing=(1.0, 1.0, 1.0), origin=None, direction=None, axes="zyx", **opts):
    """Meshes `labels` (see mesh_arrays) into a meshio.Mesh: "tetra" cells with cell data
    "material" (the label values), and "triangle" cells (the interfaces) whose "material" is
    -1 and whose label pair is in cell data "interface_labels"."""
    import meshio
    points, tets, materials, tris, tri_labels = mesh_arrays(labels, spacing, origin, direction, axes, **opts)
    return meshio.Mesh(points, [("tetra", tets), ("triangle", tris)],
                       cell_data={"material": [materials, np.full(len(tris), -1, dtype=np.int64)],
                                  "interface_labels": [np.zeros((len(tets), 2), dtype=np.int64), tri_labels]})


def mesh_sitk(image, **opts):
    """Meshes a SimpleITK label image, with its spacing, origin and direction (LPS)."""
    import SimpleITK as sitk
    a = sitk.GetArrayFromImage(image)
    return mesh(a, image.GetSpacing(), image.GetOrigin(), np.array(image.GetDirection()).reshape(3, 3), "zyx", **opts)


def mesh_nibabel(img, **opts):
    """Meshes a nibabel image (NIfTI): its affine (RAS) becomes spacing, origin and direction in LPS."""
    a = np.asarray(img.dataobj)
    affine = np.asarray(img.affine, dtype=np.float64)
    ras_to_lps = np.diag([-1.0, -1.0, 1.0])
    m = ras_to_lps @ affine[:3, :3]
    spacing = np.linalg.norm(m, axis=0)
    return mesh(np.rint(a).astype(np.int64) if a.dtype.kind == "f" else a, spacing, ras_to_lps @ affine[:3, 3],
                m / spacing, "xyz", **opts)
