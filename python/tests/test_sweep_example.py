"""python/examples/sweep_drum_speed.py run as docs/python.md says, its
printed table checked against the files its runs wrote.

Run by ctest (tests/CMakeLists.txt) with PYTHONPATH at the built module and
CES_SOURCE_DIR at the source tree. The example runs in a folder of its own,
so its out/sweep lands there.
"""
import csv
import json
import os
import re
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

EXAMPLE = Path(os.environ["CES_SOURCE_DIR"]) / "python" / "examples" / "sweep_drum_speed.py"
SPEEDS = (30, 45, 60, 75)
LINE = re.compile(r"^ *(\d+) rpm: copper grade +([\d.]+) %, recovery +([\d.]+) %$")


def conductor_copper(run):
    """Grade and recovery of copper in the conductor product, as the file has them."""
    with open(run / "products.csv", newline="") as f:
        for row in csv.DictReader(f):
            if (row["product"], row["material"]) == ("conductor", "copper"):
                return float(row["grade"]), float(row["recovery"])
    raise AssertionError(f"{run / 'products.csv'} has no conductor copper row")


class SweepExampleTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls._dir = tempfile.TemporaryDirectory()
        cls.dir = Path(cls._dir.name)
        done = subprocess.run([sys.executable, str(EXAMPLE)], cwd=cls.dir, capture_output=True,
                              text=True, timeout=300)
        if done.returncode != 0:
            raise AssertionError(f"the example failed ({done.returncode}):\n{done.stderr}")
        cls.lines = done.stdout.splitlines()

    @classmethod
    def tearDownClass(cls):
        cls._dir.cleanup()

    def printed(self):
        """{rpm: (grade %, recovery %)} from the example's lines, each of its format."""
        table = {}
        for line in self.lines:
            match = LINE.match(line)
            self.assertIsNotNone(match, f"not a line of the sweep: {line!r}")
            table[int(match[1])] = (float(match[2]), float(match[3]))
        return table

    def test_one_line_per_speed(self):
        self.assertEqual(list(self.printed()), list(SPEEDS))

    def test_each_line_is_its_runs_products(self):
        for rpm, (grade, recovery) in self.printed().items():
            with self.subTest(rpm=rpm):
                run = self.dir / "out" / "sweep" / f"{rpm}rpm"
                summary = json.loads((run / "summary.json").read_text())
                self.assertTrue(summary["complete"], summary["reason"])
                self.assertAlmostEqual(summary["simulated_time_s"], 0.7, places=6)
                resolved = (run / "scene.resolved.yaml").read_text()
                self.assertEqual(resolved.count(f'speed: "{rpm} rpm"'), 2, "drum and brush")
                file_grade, file_recovery = conductor_copper(run)
                self.assertEqual(grade, round(100 * file_grade, 1))
                self.assertEqual(recovery, round(100 * file_recovery, 1))

    def test_a_faster_drum_throws_more_copper_into_the_conductor_product(self):
        table = self.printed()
        self.assertGreater(table[SPEEDS[-1]][1], table[SPEEDS[0]][1])


if __name__ == "__main__":
    unittest.main()
