"""Third-party decoder check of the VLP-16 driver (.ci/vlp16-decoder-check.sh, docs/lidar.md).

Usage: vlp16_decoder_check.py SIM_PCAP POINTS_CSV

Decodes the simulated sensor's packets (SIM_PCAP, written by `cargo run -p vlp16 --example
sim_pcap`) with PyPI `velodyne-decoder` (its built-in VLP-16 model and calibration) and compares
every point with our decoding of the same packets (POINTS_CSV): the same number of points, in the
same order (packet, block, firing sequence, laser), each within 1 mm and 0.01 degree of azimuth,
on the same ring. Prints `N passed, N failed` last; exits non-zero on any failure.
"""

import csv
import math
import sys
from importlib import metadata

import numpy as np
import velodyne_decoder as vd

POSITION_TOLERANCE_M = 0.001
AZIMUTH_TOLERANCE_DEG = 0.01
# Laser id -> elevation (degrees), the VLP-16 user manual's table; a ring is the rank by
# elevation, as velodyne-decoder numbers them.
ELEVATIONS = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]
RING_OF_LASER = {laser: rank for rank, laser in enumerate(sorted(range(16), key=lambda l: ELEVATIONS[l]))}


def main():
    pcap_path, csv_path = sys.argv[1], sys.argv[2]
    passed, failed = 0, 0

    def check(ok, what):
        nonlocal passed, failed
        if ok:
            passed += 1
            print(f"ok   {what}")
        else:
            failed += 1
            print(f"FAIL {what}")

    payloads = [data for _, data in vd.util.iter_pcap(pcap_path) if len(data) == vd.PACKET_SIZE]
    with open(csv_path, newline="") as f:
        ours = list(csv.DictReader(f))
    config = vd.Config()
    config.model = vd.Model.VLP16
    scans = list(vd.read_pcap(pcap_path, config, as_pcl_structs=True))
    theirs = np.concatenate([points for _, points in scans])
    theirs = theirs[~np.isnan(theirs["x"])]
    check(len(payloads) > 100, f"{len(payloads)} data packets in the pcap")
    print(f"     velodyne-decoder {metadata.version('velodyne-decoder')}: {len(scans)} scans")
    check(len(ours) == len(theirs), f"point count: ours {len(ours)}, velodyne-decoder {len(theirs)}")
    n = min(len(ours), len(theirs))
    worst_m, worst_deg, bad_position, bad_azimuth, bad_ring = 0.0, 0.0, 0, 0, 0
    for k in range(n):
        o, t = ours[k], theirs[k]
        dx = float(o["x_m"]) - float(t["x"])
        dy = float(o["y_m"]) - float(t["y"])
        dz = float(o["z_m"]) - float(t["z"])
        error_m = math.sqrt(dx * dx + dy * dy + dz * dz)
        their_azimuth = math.degrees(-math.atan2(float(t["y"]), float(t["x"])))
        error_deg = abs((float(o["azimuth_deg"]) - their_azimuth + 180.0) % 360.0 - 180.0)
        worst_m, worst_deg = max(worst_m, error_m), max(worst_deg, error_deg)
        if error_m > POSITION_TOLERANCE_M:
            bad_position += 1
            if bad_position <= 5:
                print(f"     point {k} ({dict(o)}): {error_m * 1000:.3f} mm from {t}")
        if error_deg > AZIMUTH_TOLERANCE_DEG:
            bad_azimuth += 1
            if bad_azimuth <= 5:
                print(f"     point {k} ({dict(o)}): azimuth {error_deg:.4f} deg from {their_azimuth:.4f}")
        if RING_OF_LASER[int(o["laser"])] != int(t["ring"]):
            bad_ring += 1
    check(bad_position == 0, f"every point within 1 mm (worst {worst_m * 1000:.3f} mm; {bad_position} beyond)")
    check(bad_azimuth == 0, f"every azimuth within 0.01 deg (worst {worst_deg:.4f} deg; {bad_azimuth} beyond)")
    check(bad_ring == 0, f"every point on the same ring ({bad_ring} not)")
    print(f"{passed} passed, {failed} failed")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
