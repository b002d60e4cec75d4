import numpy as np
import pytest

gcmap = pytest.importorskip("gcmap", reason="gcmap is not built: build it and set PYTHONPATH=build/python")


def cloud(n=1000, seed=0):
    return np.random.default_rng(seed).uniform(-50, 50, size=(n, 3))


@pytest.mark.parametrize("ext", ["ply", "pcd", "bin"])
def test_points_round_trip_with_intensities(tmp_path, ext):
    xyz = cloud()
    intensity = np.linspace(0, 1, len(xyz))
    path = str(tmp_path / f"c.{ext}")
    gcmap.write_points(path, np.asfortranarray(np.column_stack([xyz, intensity])))  # float64, Fortran order
    points, values = gcmap.read_points(path, intensities=True)
    assert points.dtype == np.float32 and points.shape == xyz.shape and points.flags.c_contiguous
    np.testing.assert_array_equal(points, xyz.astype(np.float32))
    np.testing.assert_array_equal(values, intensity.astype(np.float32))


def test_points_without_intensity_and_xyz_bin(tmp_path):
    xyz = cloud().astype(np.float32)
    gcmap.write_points(str(tmp_path / "a.ply"), xyz)
    points, values = gcmap.read_points(str(tmp_path / "a.ply"), intensities=True)
    assert values is None
    np.testing.assert_array_equal(points, xyz)
    gcmap.write_points(str(tmp_path / "b.bin"), xyz, bin_fields="xyz")
    assert (tmp_path / "b.bin").stat().st_size == xyz.nbytes
    np.testing.assert_array_equal(gcmap.read_points(str(tmp_path / "b.bin"), bin_fields="xyz"), xyz)


def test_strided_view_is_read_in_place(tmp_path):
    big = cloud(2000)
    view = big[::2, :]  # neither C- nor F-contiguous
    gcmap.write_points(str(tmp_path / "v.pcd"), view)
    np.testing.assert_array_equal(gcmap.read_points(str(tmp_path / "v.pcd")), view.astype(np.float32))


def test_non_finite_rows_are_dropped(tmp_path):
    xyz = cloud(10)
    xyz[3, 1] = np.nan
    xyz[7, 0] = np.inf
    gcmap.write_points(str(tmp_path / "n.ply"), xyz)
    assert gcmap.read_points(str(tmp_path / "n.ply")).shape == (8, 3)


def test_missing_and_malformed_files(tmp_path):
    missing = str(tmp_path / "none.ply")
    with pytest.raises(FileNotFoundError, match="none.ply"):
        gcmap.read_points(missing)
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        gcmap.read_trajectory(str(tmp_path / "nope.txt"))
    bad = tmp_path / "bad.ply"
    bad.write_text("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1\n")
    with pytest.raises(ValueError, match="bad.ply"):
        gcmap.read_points(str(bad))
    with pytest.raises(ValueError, match="xyz"):
        gcmap.read_points(missing, bin_fields="xyzw")


@pytest.mark.parametrize("array, message", [
    (np.zeros((10, 2)), r"shape \(N, 3\) or \(N, 4\), got \(10, 2\)"),
    (np.zeros(30), r"got \(30,\)"),
    (np.zeros((10, 3), dtype=np.int32), "float32 or float64, got dtype int32"),
    (np.array([["a", "b", "c"]]), "float32 or float64"),
    (np.array([[object(), 1, 2]], dtype=object), "float32 or float64"),
])
def test_bad_arrays_raise_value_error(tmp_path, array, message):
    with pytest.raises(ValueError, match=message):
        gcmap.write_points(str(tmp_path / "x.ply"), array)


def test_unknown_extension(tmp_path):
    with pytest.raises(ValueError, match="x.xyz"):
        gcmap.write_points(str(tmp_path / "x.xyz"), cloud(5))


def test_trajectory_round_trip(tmp_path):
    sim = gcmap.simulate("small", frames=20)
    poses = sim.poses
    gcmap.write_trajectory(str(tmp_path / "t.kitti"), poses)
    back = gcmap.read_trajectory(str(tmp_path / "t.kitti"))
    assert back.shape == (20, 4, 4)
    np.testing.assert_allclose(back, poses, atol=1e-6)
    with pytest.raises(ValueError, match="rigid"):
        gcmap.write_trajectory(str(tmp_path / "u.kitti"), poses * 2)
