"""Camera rays: pinhole projection, orthographic rays, thin-lens focus, clipping."""
import numpy as np

from backend.camera import Camera


def rotation(ax, ay, az):
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def make_matrix(r, t):
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = t
    return m


# A shifted, non-square frame as Blender's view_frame gives for sensor fit + shift.
FRAME = np.array([[0.50, 0.30, -1.2], [0.50, -0.22, -1.2], [-0.36, -0.22, -1.2], [-0.36, 0.30, -1.2]])


def project(world_points, to_world, frame):
    """Independent pinhole projection: camera space, then the frame plane, then (s, t)."""
    inv = np.linalg.inv(to_world)
    pc = world_points @ inv[:3, :3].T + inv[:3, 3]
    z = frame[0, 2]
    q = pc * (z / pc[:, 2])[:, None]
    tr, br, bl, tl = frame
    s = (q[:, 0] - tl[0]) / (tr[0] - tl[0])
    t = (q[:, 1] - tl[1]) / (bl[1] - tl[1])
    return np.stack([s, t], axis=1)


def test_perspective_rays_pass_through_projected_points():
    rng = np.random.default_rng(1)
    to_world = make_matrix(rotation(0.3, -0.2, 1.1), [1.0, -4.0, 2.0])
    cam = Camera("perspective", to_world, FRAME)
    # Random points in front of the camera.
    local = np.column_stack([rng.uniform(-1, 1, 200), rng.uniform(-1, 1, 200), -rng.uniform(2, 9, 200)])
    world = local @ to_world[:3, :3].T + to_world[:3, 3]
    st = project(world, to_world, FRAME)
    o, d, tmin, tmax = cam.generate_rays(st)
    assert np.allclose(o, to_world[:3, 3])
    v = world - o
    perp = v - (v * d).sum(1)[:, None] * d
    assert np.abs(perp).max() < 1e-9
    assert np.all((v * d).sum(1) > 0)


def test_orthographic_rays_are_parallel_and_start_on_the_frame():
    to_world = make_matrix(rotation(0.1, 0.4, 0.0), [0.0, 0.0, 3.0])
    frame = np.array([[2.0, 1.0, -1.0], [2.0, -1.0, -1.0], [-2.0, -1.0, -1.0], [-2.0, 1.0, -1.0]])
    cam = Camera("orthographic", to_world, frame)
    st = np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5], [0.25, 0.75]])
    o, d, _, _ = cam.generate_rays(st)
    assert np.allclose(d, -to_world[:3, 2])
    expected_local = np.array([[-2, 1, 0], [2, -1, 0], [0, 0, 0], [-1, -0.5, 0]], float)
    assert np.allclose(o, expected_local @ to_world[:3, :3].T + to_world[:3, 3])


def test_thin_lens_rays_converge_on_the_focus_plane():
    rng = np.random.default_rng(2)
    to_world = make_matrix(rotation(0.2, 0.0, 0.5), [0.0, -5.0, 1.0])
    focus = 4.0
    cam = Camera("perspective", to_world, FRAME, focus_distance=focus, aperture_radius=0.2, blades=6)
    st = np.tile([[0.3, 0.6]], (500, 1))
    o, d, _, _ = cam.generate_rays(st, rng.random((500, 2)))
    inv = np.linalg.inv(to_world)
    oc = o @ inv[:3, :3].T + inv[:3, 3]
    dc = d @ inv[:3, :3].T
    t = (-focus - oc[:, 2]) / dc[:, 2]
    hit = oc + dc * t[:, None]
    # All rays of one film position meet at one point of the focus plane z = −focus.
    assert np.ptp(hit[:, 0]) < 1e-9 and np.ptp(hit[:, 1]) < 1e-9
    # The lens points cover the hexagonal aperture (circumradius 0.2) and not more.
    r = np.hypot(oc[:, 0], oc[:, 1])
    assert r.max() <= 0.2 + 1e-12 and r.max() > 0.17


def test_clip_start_is_measured_along_the_view_axis():
    cam = Camera("perspective", np.eye(4), FRAME, clip_start=1.0, clip_end=10.0)
    st = np.array([[0.0, 0.0], [0.5, 0.5]])
    o, d, tmin, tmax = cam.generate_rays(st)
    # The point at tmin lies on the plane z = −clip_start, the one at tmax on z = −clip_end.
    assert np.allclose((o + d * tmin[:, None])[:, 2], -1.0)
    assert np.allclose((o + d * tmax[:, None])[:, 2], -10.0)
