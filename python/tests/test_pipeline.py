import os
import subprocess

import numpy as np
import pytest

gcmap = pytest.importorskip("gcmap", reason="gcmap is not built: build it and set PYTHONPATH=build/python")

FRAMES = 12  # about 13 m of the `small` drive: a few keyframes, one submap


@pytest.fixture(scope="module")
def drive():
    sim = gcmap.simulate("small", seed=1)
    scans = [sim[i][0] for i in range(FRAMES)]
    return scans, sim.poses[:FRAMES]


@pytest.fixture(scope="module")
def mapped(drive):
    scans, _ = drive
    pipeline = gcmap.MappingPipeline(gcmap.MappingConfig(), device="cpu")
    live = []
    for i, points in enumerate(scans):
        pose, status = pipeline.add_scan(points, 0.1 * i)
        assert pose.shape == (4, 4) and status in ("keyframe", "skipped")
        live.append(pose)
    pipeline.finish()
    return pipeline, np.array(live)


def test_pipeline_recovers_the_true_poses(drive, mapped):
    _, truth = drive
    pipeline, live = mapped
    est = pipeline.trajectory
    assert est.shape == (FRAMES, 4, 4) and pipeline.odometry.shape == (FRAMES, 4, 4)
    np.testing.assert_allclose(est[0], np.eye(4), atol=1e-9)
    assert np.max(np.linalg.norm(est[:, :3, 3] - truth[:, :3, 3], axis=1)) < 0.05
    assert np.max(np.linalg.norm(live[:, :3, 3] - truth[:, :3, 3], axis=1)) < 0.3
    assert gcmap.eval.ate(truth, est)["rmse"] < 0.05


def test_pipeline_records(mapped):
    pipeline, _ = mapped
    assert len(pipeline) == FRAMES and pipeline.finished
    assert pipeline.statuses[0] == "keyframe" and len(pipeline.stamps) == FRAMES
    stats = pipeline.stats
    assert stats["frames"] == FRAMES and stats["device"] == "cpu" and "odometry" in stats["timing"]
    submaps = pipeline.submaps
    assert len(submaps) >= 1 and submaps[0]["keyframes"][0] == 0
    points = submaps[0]["points"]
    assert points.shape[1] == 3 and len(points) > 1000 and not points.flags.writeable
    assert isinstance(pipeline.factors, list) and isinstance(pipeline.loops, list)
    world = pipeline.map(0.5)
    assert world.dtype == np.float32 and world.shape[1] == 3 and 0 < len(world) < len(points) * len(submaps)
    assert pipeline.config == gcmap.MappingConfig()


def test_pipeline_after_finish_raises(mapped, drive):
    pipeline, _ = mapped
    with pytest.raises(RuntimeError, match="finish"):
        pipeline.add_scan(drive[0][0], 100.0)
    with pytest.raises(RuntimeError, match="finish"):
        pipeline.finish()


def test_bad_scans(drive):
    scans, _ = drive
    pipeline = gcmap.MappingPipeline(device="cpu")
    pipeline.add_scan(scans[0], 1.0)
    with pytest.raises(ValueError, match="points: expected shape"):
        pipeline.add_scan(scans[1][:, :2], 1.1)
    with pytest.raises(ValueError, match="times: expected shape"):
        pipeline.add_scan(scans[1], 1.1, times=np.zeros(3))
    with pytest.raises(ValueError):
        pipeline.add_scan(scans[1], 0.5)  # stamp going backwards
    pose, status = pipeline.add_scan(np.full((50, 3), np.nan), 1.1)  # NaN-only: placed by the motion model
    assert status == "unusable" and np.isfinite(pose).all()
    assert len(pipeline) == 2


def test_bad_config_names_the_key():
    c = gcmap.MappingConfig()
    with pytest.raises(ValueError, match="device"):
        gcmap.MappingPipeline(c, device="gpu")


def test_same_trajectory_as_the_cli(tmp_path, drive, mapped):
    cli = os.environ.get("GCMAP_CLI")
    if not cli or not os.path.exists(cli):
        pytest.skip("GCMAP_CLI (the gcmap binary) not given")
    scans, _ = drive
    seq = tmp_path / "seq"
    (seq / "velodyne").mkdir(parents=True)
    for i, points in enumerate(scans):
        gcmap.write_points(str(seq / "velodyne" / f"{i:06d}.bin"), points)
    (seq / "times.txt").write_text("".join(f"{0.1 * i:.6f}\n" for i in range(FRAMES)))
    (seq / "scenario.json").write_text("{}\n")  # simulated: no KITTI HDL-64 correction
    subprocess.run([cli, "map", str(seq), "-o", str(tmp_path / "out"), "--device", "cpu", "--quiet"],
                   check=True, capture_output=True)
    cli_poses = gcmap.read_trajectory(str(tmp_path / "out" / "trajectory.kitti"))
    np.testing.assert_allclose(cli_poses, mapped[0].trajectory, atol=1e-6)


def test_imu_from_python_equals_the_cli(tmp_path):
    """A simulated drive with an IMU fed through add_imu maps as `gcmap map` maps its folder."""
    cli = os.environ.get("GCMAP_CLI")
    if not cli or not os.path.exists(cli):
        pytest.skip("GCMAP_CLI (the gcmap binary) not given")
    seq, frames = tmp_path / "seq", 12
    subprocess.run([cli, "simulate", "-o", str(seq), "--scenario", "city", "--sensor", "vlp16", "--frames", str(frames),
                    "--realism", "motion_distortion", "--imu"], check=True, capture_output=True)
    subprocess.run([cli, "map", str(seq), "-o", str(tmp_path / "out"), "--device", "cpu", "--quiet",
                    "--no-elevation-estimate"], check=True, capture_output=True)
    imu = np.loadtxt(seq / "imu.txt")
    stamps = np.loadtxt(seq / "times.txt")
    pipeline = gcmap.MappingPipeline(gcmap.MappingConfig(), device="cpu")
    pipeline.add_imu(imu[0, 0], imu[0, 1:4], imu[0, 4:7])  # one sample, then the rest at once
    pipeline.add_imu(imu[1:, 0], imu[1:, 1:4], imu[1:, 4:7])
    for i in range(frames):
        points = gcmap.read_points(str(seq / "velodyne" / f"{i:06d}.bin"))
        times = np.fromfile(seq / "point_times" / f"{i:06d}.bin", dtype=np.float32)
        pipeline.add_scan(points, float(stamps[i]), times=times)
    pipeline.finish()
    assert pipeline.stats["imu"]["gyro_deskewed_sweeps"] == frames - 2
    assert pipeline.stats["imu"]["gravity"]["levelled"]  # the accelerometer levelled the map, as in the CLI
    assert "z up" in pipeline.stats["map_frame"]
    cli_poses = gcmap.read_trajectory(str(tmp_path / "out" / "trajectory.kitti"))
    np.testing.assert_allclose(cli_poses, pipeline.trajectory, atol=1e-6)
    with pytest.raises(ValueError, match="gyro: expected shape"):
        pipeline.add_imu(1.0, np.zeros(2), np.zeros(3))
