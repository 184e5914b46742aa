"""Runs a short separator scene with trajectories in both formats and reads
the VTK files back with VTK's own reader (python3-vtk9): every .vtp binary
with its arrays zlib-compressed in appended data, every frame of the .pvd
holding the particles of trajectories.csv with the same values (the last
frame as many as the summary's balance leaves in the run), the clusters'
spheres, the static machine and the turning drum at its pose.

Usage: vtk_readback.py CES_SIM SCENE
"""
import csv
import json
import math
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

try:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
    import numpy as np
except ImportError as e:
    sys.exit(f"{e}: this test needs VTK's Python module (Debian: python3-vtk9, "
             "which .ci/setup installs)")

EVERY = 0.025  # s between frames
END = 0.05     # s
DRUM_RADIUS = 0.16  # m, scenes/machines/ces_machine.yaml
DRUM_SPEED = 70 * 2 * math.pi / 60  # rad/s, clockwise seen from +z
# A flake's spheres fill hexagonal rings: 1 + 3 n (n + 1) of them, n >= 1.
FLAKE_SPHERES = {1 + 3 * n * (n + 1) for n in range(1, 20)}


def check_encoding(path):
    """Binary as ParaView users expect: every array in zlib-compressed
    appended data, none inline as ASCII or base64."""
    data = Path(path).read_bytes()
    head = data[:data.index(b"<AppendedData")]
    assert b'compressor="vtkZLibDataCompressor"' in head, path
    assert b'<AppendedData encoding="raw">' in data, path
    arrays = head.count(b"<DataArray")
    assert arrays > 0 and head.count(b'format="appended"') == arrays, path


def read_vtp(path):
    check_encoding(path)
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    if reader.GetErrorCode() != 0:
        sys.exit(f"{path}: VTK cannot read it")
    return reader.GetOutput()


def array(data, name):
    a = data.GetArray(name)
    assert a is not None, f"no array {name}"
    return vtk_to_numpy(a)


def strings(data, name):
    a = data.GetAbstractArray(name)
    assert a is not None, f"no array {name}"
    return [a.GetValue(k) for k in range(a.GetNumberOfValues())]


def points(poly):
    if poly.GetNumberOfPoints() == 0:
        return np.zeros((0, 3))
    return vtk_to_numpy(poly.GetPoints().GetData()).astype(float)


def close(a, b, what, rel=1e-8, abs_tol=0.0):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape, f"{what}: shapes {a.shape} vs {b.shape}"
    bad = ~np.isclose(a, b, rtol=rel, atol=abs_tol)
    assert not bad.any(), f"{what}: {a[bad][:3]} vs {b[bad][:3]}"


def csv_frames(out):
    frames = defaultdict(list)
    with open(out / "trajectories.csv") as f:
        for row in csv.DictReader(f):
            frames[row["time_s"]].append(row)
    return frames


def check_particles(poly, rows):
    n = len(rows)
    assert poly.GetNumberOfPoints() == n and poly.GetNumberOfVerts() == n
    pd, fd = poly.GetPointData(), poly.GetFieldData()
    col = lambda *names: np.array([[float(r[k]) for k in names] for r in rows]).reshape(
        n, len(names))
    assert list(array(pd, "id")) == [int(r["id"]) for r in rows]
    close(points(poly), col("x_m", "y_m", "z_m"), "position")
    close(array(pd, "velocity"), col("vx_mps", "vy_mps", "vz_mps"), "velocity", abs_tol=1e-15)
    close(array(pd, "angular_velocity"), col("wx_radps", "wy_radps", "wz_radps"),
          "angular_velocity", abs_tol=1e-12)
    close(array(pd, "orientation"), col("qw", "qx", "qy", "qz"), "orientation", abs_tol=1e-15)
    close(array(pd, "diameter").reshape(n, 1), col("diameter_m"), "diameter")
    close(array(pd, "charge").reshape(n, 1), col("charge_c"), "charge", abs_tol=1e-30)
    close(array(pd, "birth").reshape(n, 1), col("birth_s"), "birth", abs_tol=1e-15)
    materials, shapes = strings(fd, "material_names"), strings(fd, "shape_names")
    assert [materials[k] for k in array(pd, "material")] == [r["material"] for r in rows]
    assert strings(pd, "material_name") == [r["material"] for r in rows]
    assert [shapes[k] for k in array(pd, "shape")] == [r["shape"] for r in rows]
    assert strings(pd, "shape_name") == [r["shape"] for r in rows]
    assert set(r["shape"] for r in rows) <= {"sphere", "flake"}


def check_spheres(poly, rows):
    """A sphere particle is its own sphere; a flake's 19 spheres are
    coplanar, centred on the particle, across a principal plane."""
    pd = poly.GetPointData()
    ids, d = array(pd, "id"), array(pd, "diameter")
    centres = points(poly)
    assert poly.GetNumberOfVerts() == len(ids)
    for r in rows:
        mine = ids == int(r["id"])
        x = np.array([float(r[k]) for k in ("x_m", "y_m", "z_m")])
        c = centres[mine] - x
        if r["shape"] == "sphere":
            assert mine.sum() == 1
            close(c, np.zeros((1, 3)), "sphere centre", abs_tol=1e-7)
            close(d[mine], [float(r["diameter_m"])], "sphere diameter", rel=1e-6)
            continue
        assert mine.sum() in FLAKE_SPHERES, mine.sum()
        close(c.mean(axis=0), np.zeros(3), "flake centre", abs_tol=1e-7)
        w, qx, qy, qz = (float(r[k]) for k in ("qw", "qx", "qy", "qz"))
        rot = np.array([  # the particle's principal axes in the world, as columns
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * w), 2 * (qx * qz + qy * w)],
            [2 * (qx * qy + qz * w), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * w)],
            [2 * (qx * qz - qy * w), 2 * (qy * qz + qx * w), 1 - 2 * (qx * qx + qy * qy)]])
        out_of_plane = np.abs(c @ rot).max(axis=0)
        assert out_of_plane.min() < 1e-7, out_of_plane


def check_machine(static, moving, time):
    """The splitters and the electrode in the static part; the drum and the
    brush move, the drum's first vertex turned by the drum's angle."""
    names = strings(static.GetFieldData(), "part_names")
    static_parts = {names[k] for k in array(static.GetCellData(), "part")}
    moving_parts = {names[k] for k in array(moving.GetCellData(), "part")}
    assert static_parts == {"splitter_1", "splitter_2", "wire", "electrode"}, static_parts
    assert moving_parts == {"drum", "brush"}, moving_parts
    drum = names.index("drum")
    first = moving.GetCell(int(np.argmax(array(moving.GetCellData(), "part") == drum)))
    p = np.array(moving.GetPoint(first.GetPointId(0)))
    close([math.hypot(p[0], p[1])], [DRUM_RADIUS], "drum radius")
    turned = math.atan2(p[1], p[0])
    expected = math.remainder(-DRUM_SPEED * time, 2 * math.pi)
    assert abs(math.remainder(turned - expected, 2 * math.pi)) < 1e-9, (turned, expected)


def main():
    ces_sim, scene = sys.argv[1], sys.argv[2]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        subprocess.run([ces_sim, scene, "-o", str(out), "--quiet", "--threads", "1",
                        "--set", f"time.end={END}s", "--set", "time.until=end",
                        "--set", f"output.trajectories={{every: {EVERY} s, format: both}}"],
                       check=True)
        frames = csv_frames(out)
        pvd = ET.parse(out / "trajectories.pvd").getroot().find("Collection")
        by_time = defaultdict(dict)
        for ds in pvd.findall("DataSet"):
            by_time[ds.get("timestep")][ds.get("name")] = out / ds.get("file")
        assert len(by_time) == round(END / EVERY) + 1, list(by_time)
        # The CSV has a row per particle: frames without particles have none.
        assert set(frames) <= set(by_time), (list(frames), list(by_time))
        for time, files in by_time.items():
            assert set(files) == {"particles", "spheres", "machine (static)",
                                  "machine (moving)"}, files
            particles = read_vtp(files["particles"])
            close([array(particles.GetFieldData(), "TimeValue")[0]], [float(time)], "TimeValue")
            rows = frames.get(time, [])
            check_particles(particles, rows)
            check_spheres(read_vtp(files["spheres"]), rows)
            check_machine(read_vtp(files["machine (static)"]),
                          read_vtp(files["machine (moving)"]), float(time))
        last = max(by_time, key=float)
        assert len(frames[last]) > 50, len(frames[last])
        # The last frame is at the end: its particles are those the run
        # still holds by its own balance.
        summary = json.loads((out / "summary.json").read_text())
        close([float(last)], [summary["simulated_time_s"]], "last frame's time")
        assert len(frames[last]) == summary["balance"]["active"]["count"], len(frames[last])
        assert summary["trajectory_frames"] == len(by_time), summary["trajectory_frames"]
        print(f"{len(by_time)} frames read back, {len(frames[last])} particles in the last")


if __name__ == "__main__":
    main()
