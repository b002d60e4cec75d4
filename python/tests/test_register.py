import threading
import time

import numpy as np
import pytest

gcmap = pytest.importorskip("gcmap", reason="gcmap is not built: build it and set PYTHONPATH=build/python")


@pytest.fixture(scope="module")
def pair():
    """Two consecutive simulated scans (about 1 m apart) and their true T_target_source."""
    sim = gcmap.simulate("small", seed=3)
    (target, T_w_t), (source, T_w_s) = sim[0], sim[1]
    return target, source, np.linalg.inv(T_w_t) @ T_w_s


def pose_error(A, B):
    D = np.linalg.inv(A) @ B
    angle = np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
    return np.linalg.norm(D[:3, 3]), angle


@pytest.mark.parametrize("method", ["vgicp", "gicp"])
def test_register_recovers_the_true_motion(pair, method):
    target, source, truth = pair
    r = gcmap.register(target, source, method=method, device="cpu")
    assert r.converged and r.num_inliers > 1000 and r.overlap > 0.5
    assert r.T_target_source.shape == (4, 4) and r.T_target_source.dtype == np.float64
    dt, dr = pose_error(r.T_target_source, truth)
    assert dt < 0.01 and dr < 0.05, (dt, dr)


def test_layouts_give_the_same_result(pair):
    target, source, _ = pair
    a = gcmap.register(target, source, device="cpu").T_target_source
    b = gcmap.register(np.asfortranarray(target, dtype=np.float64),
                       np.column_stack([source, np.ones(len(source))]), device="cpu").T_target_source
    np.testing.assert_array_equal(a, b)


def test_initial_guess_is_used(pair):
    target, source, truth = pair
    r = gcmap.register(target, source, truth, device="cpu", max_iterations=1)
    assert pose_error(r.T_target_source, truth)[0] < 0.02


def test_bad_inputs(pair):
    target, source, _ = pair
    with pytest.raises(ValueError, match="source: too few finite points"):
        gcmap.register(target, np.full((100, 3), np.nan))
    with pytest.raises(ValueError, match="target: too few finite points"):
        gcmap.register(np.zeros((0, 3)), source)
    with pytest.raises(ValueError, match=r"target: expected shape \(N, 3\) or \(N, 4\)"):
        gcmap.register(target[:, :2], source)
    with pytest.raises(ValueError, match="init: expected a 4x4 matrix"):
        gcmap.register(target, source, np.eye(3))
    with pytest.raises(ValueError, match="init: is not a rigid transform"):
        gcmap.register(target, source, 2 * np.eye(4))
    with pytest.raises(ValueError, match="method"):
        gcmap.register(target, source, method="icp")
    with pytest.raises(ValueError, match="voxel"):
        gcmap.register(target, source, voxel=0)
    with pytest.raises(ValueError, match="device"):
        gcmap.register(target, source, device="tpu")


def test_gil_is_released(pair):
    """The main thread runs while another thread is inside register: were the GIL held for the
    C++ work, the main thread could only wake from its short sleep once that work had returned."""
    target, source, _ = pair
    started, finished = threading.Event(), threading.Event()

    def work():
        started.set()
        for _ in range(3):
            gcmap.register(target, source, downsample=0.1, device="cpu")
        finished.set()

    worker = threading.Thread(target=work)
    worker.start()
    started.wait()
    time.sleep(0.01)
    busy = not finished.is_set()
    worker.join()
    assert busy and finished.is_set()
