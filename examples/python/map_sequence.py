"""Maps a KITTI-layout folder (velodyne/*.bin, times.txt, poses.txt) and prints the KITTI metric.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/map_sequence.py SEQ [--frames N]

poses.txt is taken to be in the LiDAR frame, as `gcmap simulate` writes it (KITTI's official
poses are in camera 0: convert them with calib.txt, or use `gcmap eval --calib`).
"""
import argparse
import pathlib

import numpy as np

import gcmap

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("sequence", type=pathlib.Path)
parser.add_argument("--frames", type=int, default=0, help="map only the first N scans (0: all)")
args = parser.parse_args()

files = sorted((args.sequence / "velodyne").glob("*.bin"))[:args.frames or None]
times_txt = args.sequence / "times.txt"
stamps = np.loadtxt(times_txt, ndmin=1) if times_txt.exists() else 0.1 * np.arange(len(files))
simulated = (args.sequence / "scenario.json").exists()  # else KITTI's own HDL-64 scans

pipeline = gcmap.MappingPipeline(gcmap.MappingConfig(), device="auto", kitti_hdl64=not simulated)
for i, path in enumerate(files):
    pose, status = pipeline.add_scan(gcmap.read_points(str(path)), stamps[i])
    print(f"\rframe {i + 1}/{len(files)}: {status:8s}", end="", flush=True)
pipeline.finish()
print(f"\n{len(files)} frames, {len(pipeline.submaps)} submaps, {pipeline.stats['frames_per_second']:.1f} frames/s")

if (args.sequence / "poses.txt").exists():
    gt = gcmap.read_trajectory(str(args.sequence / "poses.txt"))[:len(files)]
    kitti = gcmap.eval.kitti(gt, pipeline.trajectory)
    print(f"KITTI relative error: {kitti['translation_percent']:.3f} % translation, "
          f"{kitti['rotation_deg_per_100m']:.4f} deg/100 m ({kitti['num_segments']} segments); "
          f"ATE {gcmap.eval.ate(gt, pipeline.trajectory)['rmse']:.3f} m")
