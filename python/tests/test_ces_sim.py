"""The Python module against what the same runs write and what ces-sim says.

Run by ctest (tests/CMakeLists.txt) with PYTHONPATH at the built module,
CES_SIM_BINARY at ces-sim and CES_SOURCE_DIR at the source tree; with
CES_SIM_WITHOUT_NUMPY=1 numpy cannot be imported, so the tables are lists.
"""
import csv
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

WITHOUT_NUMPY = os.environ.get("CES_SIM_WITHOUT_NUMPY") == "1"
if WITHOUT_NUMPY:
    sys.modules["numpy"] = None  # import numpy raises ImportError
else:
    try:
        import numpy  # noqa: F401
    except ImportError:
        sys.exit(f"{sys.executable} cannot import numpy, so the module's arrays are not "
                 "tested: install python3-numpy, or configure with "
                 "-DPython3_EXECUTABLE= an interpreter that has it")

import ces_sim  # noqa: E402

SOURCE = Path(os.environ["CES_SOURCE_DIR"])
TINY = SOURCE / "tests" / "scenes" / "tiny.yaml"
BAD = SOURCE / "tests" / "scenes" / "bad.yaml"
TINY_STEPS = 400  # tiny.yaml: 0.4 s at 1 ms


def read_csv(path):
    """The file's header and its columns of text cells, by the csv module."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    return header, {name: [row[k] for row in rows[1:]] for k, name in enumerate(header)}


def as_list(values):
    return values.tolist() if hasattr(values, "tolist") else list(values)


class Case(unittest.TestCase):
    def setUp(self):
        self._dir = tempfile.TemporaryDirectory()
        self.dir = Path(self._dir.name)

    def tearDown(self):
        self._dir.cleanup()

    def assertSameAsFile(self, table, path):
        """Every column of the file, in its order, with the same values exactly."""
        header, cells = read_csv(path)
        self.assertEqual(list(table), header)
        for name in header:
            values = table[name]
            if WITHOUT_NUMPY:
                self.assertIsInstance(values, list, name)
            else:
                self.assertIn(values.dtype.kind, "ifU", name)
            values = as_list(values)
            self.assertEqual(len(values), len(cells[name]), name)
            for value, cell in zip(values, cells[name]):
                if isinstance(value, str):
                    self.assertEqual(value, cell, name)
                elif isinstance(value, int):
                    self.assertEqual(value, int(cell), name)
                elif math.isnan(float(cell)):
                    self.assertTrue(math.isnan(value), name)
                else:
                    self.assertEqual(value, float(cell), name)


class RunTest(Case):
    def test_tables_are_the_files_the_run_wrote(self):
        result = ces_sim.load(TINY).run(self.dir / "run")
        self.assertTrue(result.complete, result.reason)
        self.assertEqual(result.reason, "")
        self.assertEqual(Path(result.out_dir), self.dir / "run")
        for name in ("products", "bins", "crossings", "trajectories"):
            with self.subTest(table=name):
                self.assertSameAsFile(getattr(result, name), self.dir / "run" / (name + ".csv"))
        bins = result.bins
        copper = [n for n, m in zip(as_list(bins["count"]), as_list(bins["material"])) if m == "copper"]
        self.assertGreater(sum(copper), 0)

    def test_column_types_follow_the_names(self):
        bins = ces_sim.load(TINY).run(self.dir / "run").bins
        kinds = {name: type(as_list(values)[0]) for name, values in bins.items()}
        self.assertEqual(kinds["collector"], str)
        self.assertEqual(kinds["bin"], int)
        self.assertEqual(kinds["material"], str)
        self.assertEqual(kinds["count"], int)
        self.assertEqual(kinds["from_m"], float)
        self.assertEqual(kinds["mass_kg"], float)

    def test_ratios_spins_and_distances_are_floats_even_when_whole(self):
        path = self.dir / "t.csv"
        path.write_text("qw,wx_radps,max_penetration_rel,grade_error,w1_mm fr4 at bins,count\n"
                        "1,0,0,0,2,3\n")
        table = ces_sim.read_csv(path)
        kinds = {name: type(as_list(values)[0]) for name, values in table.items()}
        for name in ("qw", "wx_radps", "max_penetration_rel", "grade_error", "w1_mm fr4 at bins"):
            self.assertEqual(kinds[name], float, name)
        self.assertEqual(kinds["count"], int)

    def test_summary_is_summary_json(self):
        result = ces_sim.load(TINY, seed=5).run(self.dir / "run")
        self.assertTrue(result.summary["complete"])
        self.assertEqual(result.summary["steps"], TINY_STEPS)
        self.assertEqual(result.summary["seed"], 5)

    def test_results_stay_when_the_folder_is_run_again(self):
        scene = ces_sim.load(TINY)
        first = scene.run(self.dir / "run")
        counts = as_list(first.bins["count"])
        ces_sim.load(TINY, set={"feeds.hopper.duration": "0.01 s"}).run(self.dir / "run")
        self.assertEqual(as_list(first.bins["count"]), counts)

    def test_overrides_seed_and_threads(self):
        scene = ces_sim.load(TINY, set={"time.end": "0.05 s", "seed": 3}, seed=7)
        self.assertEqual(scene.end_time, 0.05)
        self.assertEqual(scene.seed, 7)
        listed = ces_sim.load(TINY, set=["time.end=0.05 s"])
        self.assertEqual(listed.end_time, 0.05)

    def test_thread_count_changes_no_byte(self):
        scene = ces_sim.load(TINY)
        one = scene.run(self.dir / "one", threads=1)
        two = scene.run(self.dir / "two", threads=2)
        self.assertEqual(one.summary["threads"], 1)
        self.assertEqual(two.summary["threads"], 2)
        for name in ("products.csv", "bins.csv", "crossings.csv"):
            self.assertEqual((self.dir / "one" / name).read_bytes(),
                             (self.dir / "two" / name).read_bytes(), name)

    def test_no_trajectories_is_none(self):
        scene = ces_sim.load(SOURCE / "tests" / "scenes" / "study_drop.yaml")
        self.assertIsNone(scene.run(self.dir / "run").trajectories)


class ProgressTest(Case):
    def test_called_as_the_run_goes_and_at_its_end(self):
        seen = []
        result = ces_sim.load(TINY).run(
            self.dir / "run", progress=lambda *args: seen.append(args), progress_every=0)
        self.assertTrue(result.complete)
        self.assertEqual(len(seen), TINY_STEPS)
        times = [t for t, _, _ in seen]
        self.assertEqual(times, sorted(times))
        self.assertAlmostEqual(seen[0][0], 0.001, delta=1e-12)
        self.assertEqual(seen[-1][2], 1.0)
        for time, particles, fraction in seen:
            self.assertIsInstance(particles, int)
            self.assertAlmostEqual(fraction, time / 0.4, delta=1e-12)
        self.assertGreater(max(p for _, p, _ in seen), 0)

    def test_false_stops_the_run(self):
        calls = []

        def stop_at_ten(time, particles, fraction):
            calls.append(time)
            return None if len(calls) < 10 else False

        result = ces_sim.load(TINY).run(
            self.dir / "run", progress=stop_at_ten, progress_every=0)
        self.assertFalse(result.complete)
        self.assertEqual(result.reason, "stopped by the caller")
        self.assertEqual(len(calls), 10)
        self.assertEqual(Path(result.out_dir), self.dir / "run" / "partial")
        self.assertEqual(result.summary["steps"], 10)
        self.assertEqual(result.summary["reason"], "stopped by the caller")
        self.assertSameAsFile(result.bins, self.dir / "run" / "partial" / "bins.csv")
        self.assertFalse((self.dir / "run" / "bins.csv").exists())

    def test_an_exception_stops_the_run_and_comes_back(self):
        def fail(time, particles, fraction):
            raise ZeroDivisionError("from the callback")

        with self.assertRaisesRegex(ZeroDivisionError, "from the callback"):
            ces_sim.load(TINY).run(self.dir / "run", progress=fail, progress_every=0)
        summary = json.loads((self.dir / "run" / "partial" / "summary.json").read_text())
        self.assertEqual(summary["steps"], 1)

    def test_ctrl_c_stops_the_run_cleanly(self):
        def interrupt(time, particles, fraction):
            os.kill(os.getpid(), signal.SIGINT)

        with self.assertRaises(KeyboardInterrupt):
            ces_sim.load(TINY).run(self.dir / "run", progress=interrupt, progress_every=0)
        summary = json.loads((self.dir / "run" / "partial" / "summary.json").read_text())
        self.assertEqual(summary["reason"], "interrupted by SIGINT")
        with self.assertRaises(KeyboardInterrupt):  # Python's own handler is back
            os.kill(os.getpid(), signal.SIGINT)

    def test_a_run_from_a_progress_callback_is_an_error(self):
        scene = ces_sim.load(TINY)

        def nested(time, particles, fraction):
            scene.run(self.dir / "inner")

        with self.assertRaisesRegex(RuntimeError, "cannot be called from a progress callback"):
            scene.run(self.dir / "run", progress=nested, progress_every=0)
        scene.run(self.dir / "after")  # the thread runs again

    def test_not_callable_is_a_type_error(self):
        with self.assertRaises(TypeError):
            ces_sim.load(TINY).run(self.dir / "run", progress=3)


class ErrorTest(Case):
    def test_scene_error_says_what_ces_sim_says(self):
        cli = subprocess.run([os.environ["CES_SIM_BINARY"], "validate", str(BAD)],
                             capture_output=True, text=True)
        self.assertEqual(cli.returncode, 2)
        with self.assertRaises(ces_sim.SceneError) as caught:
            ces_sim.load(BAD)
        self.assertIsInstance(caught.exception, ValueError)
        self.assertEqual(str(caught.exception), cli.stderr.rstrip("\n"))
        self.assertIn(f"{BAD}:9:5: feeds[0].rte: unknown key 'rte'", str(caught.exception))
        where = [(d.file, d.line, d.key) for d in caught.exception.diagnostics]
        self.assertIn((str(BAD), 6, "materials.copper.density"), where)

    def test_bad_override_names_the_key(self):
        with self.assertRaises(ces_sim.SceneError) as caught:
            ces_sim.load(TINY, set={"time.end": "0.05 s", "materials.copper.densty": 1})
        self.assertRegex(str(caught.exception), r"^--set:2:1: materials\.copper\.densty: ")

    def test_include_paths_as_on_the_command_line(self):
        scene = SOURCE / "scenes" / "validation" / "ces_feedrate.yaml"
        with self.assertRaises(ces_sim.SceneError) as caught:
            ces_sim.load(scene)
        self.assertIn("outside the folder of ces_feedrate.yaml", str(caught.exception))
        loaded = ces_sim.load(scene, include_paths=[SOURCE / "scenes"])
        self.assertEqual(loaded.name, "ces_feedrate")

    def test_missing_file_names_it(self):
        with self.assertRaisesRegex(ces_sim.SceneError, "nowhere.yaml"):
            ces_sim.load(self.dir / "nowhere.yaml")

    def test_bad_arguments(self):
        with self.assertRaises(ValueError):
            ces_sim.load(TINY, seed=-1)
        with self.assertRaises(TypeError):
            ces_sim.load(TINY, set="time.end=1 s")
        with self.assertRaises(ValueError):
            ces_sim.load(TINY).run(self.dir / "run", threads=0)


if __name__ == "__main__":
    unittest.main()
