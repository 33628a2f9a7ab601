"""The mesh path of the field wall model (boundary/mesh_field.py, mesh_integral.py, backends/field_grid.py):
the exact kernel integral I of a mesh's solid against independent quadratures, the grid read through
the device functions against it, the disk cache and the refusals.

Units: H the kernel support; I is the solid's kernel mass (dimensionless), φ > 0 outside the solid.
Tolerances (each named where used):
  EXACT_FACE    1e-12  the evaluator on a flat face vs the closed-form half space Φ: both exact
  EXACT_ON_FACE 2e-8   the same on the face itself, evaluated 1e-8 H off it: 1e-8 |dΦ/dq| = 1.4e-8
  EXACT_RAY     5e-5   the evaluator vs a ray quadrature (exact radial integral per ray, 200 x 400
                       directions): the ray rule's own error, measured 2.3e-5 / 1.1e-5 / 3e-6 / 5e-8 at
                       100 / 200 / 400 / 800 polar nodes on these features, so 5e-5 is 4x its error at 200
  EXACT_BALL    3e-4   the evaluator on an icosphere (nsub 5) vs the exact ball of the same volume: the
                       facets' ripple (facet depth ≈ 1e-5 m at R = 50 mm, H = 20 mm), measured 1.4e-4
  GRID_I        1e-3   grid vs exact, h_g = H/8: the brief's budget; Catmull-Rom's 1D face error is 5.4e-4
                       (brief section 7), measured 6.5e-4 at the rotated box's edges and corners, 4.4e-4
                       on the sphere (6.7e-4 on the 0.2 m bunny, not run here)
  GRID_GRAD     0.05   H |grid ∇I − exact ∇I|, h_g = H/8: the brief's budget (1D Catmull-Rom: 0.041),
                       measured 0.017 (box), 0.029 (sphere), 0.039 (bunny, not run here)
  GRID_PHI      0.5 h_g  trilinear φ vs the exact distance: a distance has kinks at edges, corners and the
                       medial planes, where linear interpolation is off by up to half a cell; measured 0.33
"""

import math

import igl
import numpy as np
import pytest

from ipsph.backends import field_grid as fg
from ipsph.boundary.mesh_field import MEMORY_FRACTION, MeshField, field_for_spec, mesh_field
from ipsph.boundary.mesh_integral import MeshIntegral
from ipsph.config import BoundarySpec, Transform
from ipsph.errors import MeshError
from ipsph.geometry.meshes import box_mesh, mesh_arrays, signed_volume

H = 0.02  # r = 5 mm
EXACT_FACE, EXACT_ON_FACE, EXACT_RAY, EXACT_BALL = 1e-12, 2e-8, 5e-5, 3e-4
GRID_I, GRID_GRAD, GRID_PHI = 1e-3, 0.05, 0.5

BOX_LO = np.array([-0.05, -0.04, -0.03])
BOX_HI = -BOX_LO
ROT = np.array([0.3, -0.5, 0.7])  # an arbitrary rotation vector (rad)
SHIFT = np.array([0.011, -0.007, 0.003])


def _rotation(v):
    th = np.linalg.norm(v)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / th
    return np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * k @ k


R = _rotation(ROT)


# -- the kernel and its closed forms (H = 1) ---------------------------------------------------------
def _w(q):
    q = np.asarray(q, dtype=np.float64)
    return np.where(q <= 0.5, 8 / np.pi * (1 - 6 * q**2 + 6 * q**3), np.where(q <= 1, 16 / np.pi * (1 - q) ** 3, 0.0))


def _phi_half(q):
    """Kernel mass beyond a plane at signed distance qH (q > 0: the point is outside the solid)."""
    q = np.asarray(q, dtype=np.float64)
    a = np.abs(q)
    v = np.where(
        a <= 0.5, 0.5 - 7 * a / 5 + 8 * a**3 / 3 - 24 * a**5 / 5 + 16 * a**6 / 5, 8 / 15 * (1 - a) ** 5 * (1 + 2 * a)
    )
    v = np.where(a >= 1, 0.0, v)
    return np.where(q >= 0, v, 1 - v)


def _cumulative(r):
    """F(ρ) = ∫₀^ρ W s² ds (H = 1), F(1) = 1/4π."""
    q = np.clip(r, 0.0, 1.0)
    inner = (8 * q**6 - 48 * q**5 / 5 + 8 * q**3 / 3) / np.pi
    outer = (-8 * q**6 / 3 + 48 * q**5 / 5 - 12 * q**4 + 16 * q**3 / 3 - 1 / 60) / np.pi
    return np.where(q <= 0.5, inner, outer)


def _gauss(f, cuts, n=20):
    x, w = np.polynomial.legendre.leggauss(n)
    total = 0.0
    for a, b in zip(cuts[:-1], cuts[1:]):
        total += 0.5 * (b - a) * np.sum(w * f(0.5 * (a + b) + 0.5 * (b - a) * x))
    return total


def _half_space_quadrature(y):
    """∫_{z > y} W dV = ∫_y^1 2π ∫_z^1 W(ρ) ρ dρ dz, Gauss on the spline's pieces (exact for them)."""

    def disk(z):
        return np.array([2 * np.pi * _gauss(lambda r: _w(r) * r, sorted({zi, max(zi, 0.5), 1.0})) for zi in z])

    return _gauss(disk, sorted({y, max(y, 0.5), 1.0}))


def _ray_box(p, lo, hi, n):
    """I at p (box frame, H = 1) by directions (Gauss in cos θ x n, uniform in azimuth x 2n) with each
    ray's chord through the axis-aligned box integrated exactly: Σ w_ω [F(t_out) − F(t_in)]."""
    mu, wmu = np.polynomial.legendre.leggauss(n)
    az = (np.arange(2 * n) + 0.5) * np.pi / n
    st = np.sqrt(1 - mu**2)
    d = np.stack([np.outer(st, np.cos(az)), np.outer(st, np.sin(az)), np.repeat(mu[:, None], 2 * n, 1)], -1)
    d = d.reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - p) / d, (hi - p) / d
    t_in = np.clip(np.nanmax(np.minimum(t1, t2), axis=1), 0, 1)
    t_out = np.clip(np.nanmin(np.maximum(t1, t2), axis=1), 0, 1)
    chord = np.where(t_out > t_in, _cumulative(t_out) - _cumulative(t_in), 0.0)
    return float(np.sum(np.repeat(wmu, 2 * n) * (np.pi / n) * chord))


def _ball(s, radius):
    """I of a ball of `radius` at distance s from its centre (H = 1): ∫ W(ρ) × (area of the sphere of
    radius ρ about the point inside the ball) dρ, Gauss between the kinks."""
    out = []
    for si in np.atleast_1d(s):
        cuts = sorted({0.0, 0.5, 1.0} | {v for v in (abs(si - radius), si + radius) if 0 < v < 1})

        def f(r, si=si):
            cos_a = np.clip((si**2 + r**2 - radius**2) / (2 * si * r), -1, 1)
            return _w(r) * 2 * np.pi * r**2 * (1 - cos_a)

        out.append(_gauss(f, cuts))
    return np.array(out)


# -- geometry ----------------------------------------------------------------------------------------
def _feature_points(n, rng):
    """n points each within H of one face, of one edge (two faces) and of one corner (three), box frame."""
    pts = []
    for kind in (1, 2, 3):
        for _ in range(n):
            p = rng.uniform(BOX_LO, BOX_HI)
            for a in rng.permutation(3)[:kind]:
                p[a] = (BOX_HI[a] if rng.random() < 0.5 else BOX_LO[a]) + rng.uniform(-1, 1) * H
            pts.append(p)
    return np.array(pts)


def _box_world():
    v, f = mesh_arrays(box_mesh(BOX_LO, BOX_HI))
    return v @ R.T + SHIFT, f


def _exact(verts, faces, pts):
    integral = MeshIntegral(verts, faces, H, verts.min(axis=0) - 2 * H, verts.max(axis=0) + 2 * H)
    return integral(pts, igl.signed_distance(pts, verts, faces)[0])


def _exact_gradient(verts, faces, pts, step=1e-2 * H):
    """Central differences of the exact I (truncation ~(step/H)²/6 ≈ 2e-5, rounding ≈ 1e-5 in H∇I)."""
    g = np.zeros_like(pts)
    for a in range(3):
        e = np.zeros(3)
        e[a] = step
        g[:, a] = (_exact(verts, faces, pts + e) - _exact(verts, faces, pts - e)) / (2 * step)
    return g


@pytest.fixture(scope="module")
def box_field():
    verts, faces = _box_world()
    return verts, faces, mesh_field((verts, faces), H, name="rotated box", use_cache=False)


# -- the exact integral ------------------------------------------------------------------------------
def test_half_space_closed_form_against_quadrature():
    for q in (0, 1 / 8, 1 / 4, 3 / 8, 1 / 2, 3 / 4):
        assert abs(_phi_half(q) - _half_space_quadrature(q)) < 1e-12, q
    assert abs(_phi_half(0.25) - 0.1877604) < 1e-7 and abs(_phi_half(0.5) - 1 / 30) < 1e-15
    q = np.linspace(-1.2, 1.2, 49)
    assert np.allclose(_phi_half(q) + _phi_half(-q), 1.0, atol=1e-15, rtol=0)


def test_exact_integral_on_a_face_is_the_half_space():
    verts, faces = _box_world()
    y = np.linspace(-1.1, 1.1, 23) * H  # along the +z face's normal through a point off its diagonal
    p = np.column_stack([np.full_like(y, 0.013), np.full_like(y, -0.008), BOX_HI[2] + y]) @ R.T + SHIFT
    err = np.abs(_exact(verts, faces, p) - _phi_half(y / H))
    assert np.delete(err, 11).max() < EXACT_FACE
    assert err[11] < EXACT_ON_FACE  # y = 0: evaluated 1e-8 H off the surface


def test_exact_integral_against_ray_quadrature_at_edges_and_corners():
    verts, faces = _box_world()
    pb = _feature_points(8, np.random.default_rng(7))
    exact = _exact(verts, faces, pb @ R.T + SHIFT)
    ray = np.array([_ray_box(p / H, BOX_LO / H, BOX_HI / H, 200) for p in pb])
    assert np.abs(exact - ray).max() < EXACT_RAY


def test_exact_integral_of_a_sphere_mesh():
    import pyvista as pv

    radius = 0.05
    mesh = pv.Icosphere(radius=radius, nsub=5)
    verts, faces = mesh_arrays(mesh)
    r_eq = (3 * abs(signed_volume(mesh)) / (4 * np.pi)) ** (1 / 3)  # the facets' volume-equivalent ball
    rng = np.random.default_rng(2)
    u = rng.normal(size=(200, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    s = radius + rng.uniform(-1, 1, 200) * H
    assert np.abs(_exact(verts, faces, u * s[:, None]) - _ball(s / H, r_eq / H)).max() < EXACT_BALL


# -- the grid ----------------------------------------------------------------------------------------
def test_grid_on_a_rotated_box(box_field):
    verts, faces, field = box_field
    assert field.spacing == H / 8 and not field.from_cache and field.nbytes == 8 * np.prod(field.dims) + 72
    pts = _feature_points(150, np.random.default_rng(3)) @ R.T + SHIFT
    ki, grad, phi, grad_phi = field.sample(pts)
    assert np.abs(ki - _exact(verts, faces, pts)).max() < GRID_I
    err = H * np.linalg.norm(grad - _exact_gradient(verts, faces, pts), axis=1)
    assert err.max() < GRID_GRAD
    dist = igl.signed_distance(pts, verts, faces)[0]  # > 0 outside
    assert np.abs(phi - dist).max() < GRID_PHI * field.spacing
    far = np.abs(dist) > field.spacing
    assert np.all(np.sign(phi[far]) == np.sign(dist[far]))
    # the nodes: I = 1 deep inside, 0 far outside, within [0, 1] everywhere
    assert field.kernel_integral.min() >= 0.0 and field.kernel_integral.max() <= 1.0
    assert np.all(field.kernel_integral[field.phi < -H] == 1.0) and np.all(field.kernel_integral[field.phi > H] == 0.0)


def test_nodes_on_the_surface():
    """An axis-aligned box whose faces, edges and corners hold nodes (origin and faces on multiples of
    h_g): there the divergence-theorem sum has no limit (each face's share depends on the way in), so
    the evaluator steps 1e-8 H off the surface. Face nodes read 1/2, edge nodes 1/4 and corner nodes
    1/8 (the half, quarter and eighth of the kernel's mass; float32 nodes: 1e-7)."""
    lo, hi = np.zeros(3), np.array([0.06, 0.05, 0.045])
    field = mesh_field(box_mesh(lo, hi), H, use_cache=False)
    nx, ny, nz = field.dims
    axes = [field.origin[a] + field.spacing * np.arange(n) for a, n in enumerate((nx, ny, nz))]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    p = np.stack([x, y, z], -1)
    on = np.isclose(p, lo, rtol=0, atol=1e-12) | np.isclose(p, hi, rtol=0, atol=1e-12)
    clear = on | ((p - lo >= H - 1e-12) & (hi - p >= H - 1e-12))  # each axis: on a face, or H clear of both
    on_box = np.all((p >= lo - 1e-12) & (p <= hi + 1e-12), axis=-1) & clear.all(axis=-1)
    for n_faces, share, count in ((1, 0.5, 174), (2, 0.25, 68), (3, 0.125, 8)):
        sel = on_box & (on.sum(axis=-1) == n_faces)
        assert sel.sum() == count and np.abs(field.kernel_integral[sel] - share).max() < 1e-7


def test_grid_on_a_sphere():
    import pyvista as pv

    radius = 0.05
    mesh = pv.Icosphere(radius=radius, nsub=3)  # coarse facets keep the build short: grid vs this mesh's own I
    verts, faces = mesh_arrays(mesh)
    field = mesh_field(mesh, H, name="sphere", use_cache=False)
    rng = np.random.default_rng(4)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    pts = u * (radius + rng.uniform(-1, 1, 400) * H)[:, None]
    ki, grad, _, _ = field.sample(pts)
    assert np.abs(ki - _exact(verts, faces, pts)).max() < GRID_I
    assert (H * np.linalg.norm(grad - _exact_gradient(verts, faces, pts), axis=1)).max() < GRID_GRAD


def _linear_grid(dtype):
    """A 6x5x7 grid (h = 0.1, origin (1, 2, 3)) holding φ = I = 0.3 + 2x − y + 0.5z at its nodes."""
    hdr = np.zeros((1, fg.HEADER))
    hdr[0, :3] = (1.0, 2.0, 3.0)
    hdr[0, fg.HDR_INV_H] = 10.0
    hdr[0, fg.HDR_NX : fg.HDR_NZ + 1] = (6, 5, 7)
    hdr[0, fg.HDR_PAD] = 0.25
    z, y, x = np.meshgrid(3 + 0.1 * np.arange(7), 2 + 0.1 * np.arange(5), 1 + 0.1 * np.arange(6), indexing="ij")
    f = (0.3 + 2 * x - y + 0.5 * z).ravel()
    pool = np.empty(2 * f.size, dtype=dtype)
    pool[0::2], pool[1::2] = f, f
    return MeshField("linear", hdr, pool, 0.8, 0.1, 0, 0.0, False)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_interpolants_reproduce_a_linear_field_and_the_outside(dtype):
    """Catmull-Rom and trilinear are exact on linear data away from the clamped faces (so each
    weight set sums to one and the derivative weights to zero); off the grid: I = 0, φ = pad + distance."""
    field = _linear_grid(dtype)
    rng = np.random.default_rng(5)
    pts = rng.uniform((1.1, 2.1, 3.1), (1.4, 2.3, 3.5), (50, 3))  # one cell in from the faces
    ki, grad, phi, grad_phi = field.sample(pts)
    exact = 0.3 + pts @ np.array([2.0, -1.0, 0.5])
    tol = 1e-5 if dtype == np.float32 else 1e-12  # float32 nodes of values ≈ 3
    assert np.abs(ki - exact).max() < tol and np.abs(phi - exact).max() < tol
    assert np.abs(grad - [2.0, -1.0, 0.5]).max() < 20 * tol and np.abs(grad_phi - [2.0, -1.0, 0.5]).max() < 20 * tol
    ki, grad, phi, grad_phi = field.sample([[0.7, 2.2, 3.3], [1.2, 2.2, 4.0]])
    assert np.all(ki == 0.0) and np.all(grad == 0.0)
    assert np.allclose(phi, [0.25 + 0.3, 0.25 + 0.4]) and np.allclose(grad_phi, [[-1, 0, 0], [0, 0, 1]])


# -- cache and refusals ------------------------------------------------------------------------------
def test_cache_hit_and_miss(tmp_path, monkeypatch):
    cache_dir = tmp_path / "cache"
    monkeypatch.setenv("IPSPH_CACHE_DIR", str(cache_dir))
    path = tmp_path / "box.stl"
    box_mesh((0, 0, 0), (0.04, 0.03, 0.02)).save(path)
    first = mesh_field(path, H)
    (stored,) = cache_dir.iterdir()
    again = mesh_field(path, H)
    assert not first.from_cache and again.from_cache
    assert np.array_equal(first.pool, again.pool) and np.array_equal(first.header, again.header)
    assert not mesh_field(path, H, scale=(1.0, 1.0, 2.0)).from_cache  # the scale is part of the key
    spec = BoundarySpec(name="lid", shape="mesh", mesh=str(path), transform=Transform(scale=(1.0, 1.0, 2.0)))
    assert field_for_spec(spec, H).from_cache  # a [[boundary]]'s file and scale: the same grid
    assert not mesh_field(path, 1.5 * H).from_cache  # so is H
    stored.write_bytes(b"not a grid")
    rebuilt = mesh_field(path, H)  # a damaged file is rebuilt, not trusted
    assert not rebuilt.from_cache and np.array_equal(rebuilt.pool, first.pool)
    assert mesh_field(path, H).from_cache


def _bowtie():
    """Two tetrahedra sharing an edge: closed and paired, but the edge has four triangles."""
    a = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0], [0, 0, -1.0]]) * 0.05
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [0, 4, 1], [0, 1, 5], [0, 5, 4], [1, 4, 5]])
    return a, f


@pytest.mark.parametrize("case", ["open", "non-manifold", "nan", "memory"])
def test_refusals(case, tmp_path, monkeypatch):
    monkeypatch.setenv("IPSPH_CACHE_DIR", str(tmp_path))
    v, f = mesh_arrays(box_mesh((0, 0, 0), (0.05, 0.05, 0.05)))
    source, support, words = {
        "open": ((v, f[1:]), H, "3 open"),
        "non-manifold": (_bowtie(), H, "1 non-manifold"),
        "nan": ((np.where(np.arange(8)[:, None] == 3, np.nan, v), f), H, "NaN"),
        "memory": (
            (v, f),
            1e-4,
            f"{MEMORY_FRACTION:.0%} of the available memory",
        ),  # 4e12 nodes: refused, not allocated
    }[case]
    with pytest.raises(MeshError) as err:
        mesh_field(source, support, name=f"the {case} mesh")
    msg = str(err.value)
    assert msg.startswith(f"mesh the {case} mesh: ") and words in msg and "\n" not in msg
    assert not any(tmp_path.iterdir())  # nothing cached


def test_device_functions_compile_for_cuda():
    """The grid readers compile as numba-cuda device functions (float32 and float64 pools), where
    numba-cuda and the CUDA compiler libraries (NVRTC, NVVM) are installed: no GPU needed."""
    pathfinder = pytest.importorskip("cuda.pathfinder")
    for lib in ("nvrtc", "nvvm"):
        try:
            pathfinder.load_nvidia_dynamic_lib(lib)
        except Exception as exc:  # noqa: BLE001 - not installed here
            pytest.skip(f"no CUDA compiler library {lib}: {str(exc).splitlines()[0]}")
    cuda = pytest.importorskip("ipsph.backends._cuda").cuda
    if cuda is None:
        pytest.skip("numba-cuda is not installed")
    import numba

    def kernel(hdr, pool, pts, out):
        i = cuda.grid(1)
        if i < pts.shape[0]:
            a, b, c, d = fg.grid_kernel_integral(hdr, 0, pool, pts[i, 0], pts[i, 1], pts[i, 2])
            e, f, g, h = fg.grid_distance(hdr, 0, pool, pts[i, 0], pts[i, 1], pts[i, 2])
            out[i, 0], out[i, 1] = a + b + c + d, e + f + g + h

    m2 = numba.float64[:, :]
    for pool in (numba.float32[:], numba.float64[:]):
        ptx, _ = cuda.compile_ptx(kernel, (m2, pool, m2, m2), cc=(9, 0))
        assert "malloc" not in ptx and "call.uni" not in ptx  # no allocation, everything inlined
