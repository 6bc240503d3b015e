"""Unit tests of bench/throughput/report.py: `python3 -m unittest discover -s bench/throughput`.

The parsers are checked on lines in the exact format zeroset and the harnesses print, the floors
on figures whose verdicts follow from the issue's thresholds by hand arithmetic.
"""
import json
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import report as R  # noqa: E402
from report import NA  # noqa: E402

RENDER = ("rendered 1280x720 at 1 spp (6 objects) on 2 threads: trace 0.296 s (3.11 Mrays/s), wall 0.441 s "
          "(load+BVH 0.012 s, write 0.086 s; CPU 0.13 s)")


class Parse(unittest.TestCase):
    def test_render_line(self):
        d = R.parse_render("wrote x.exr\n" + RENDER + "\n")
        self.assertEqual((d["w"], d["h"], d["spp"], d["threads"]), (1280, 720, 1, 2))
        self.assertEqual(d["trace_s"], 0.296)
        self.assertEqual(d["mrays"], 3.11)
        self.assertEqual(d["load_s"], 0.012)
        self.assertEqual(d["wall_s"], 0.441)

    def test_render_line_missing_is_an_error_naming_the_output(self):
        with self.assertRaises(ValueError) as e:
            R.parse_render("error: scene.ron:3:5: unknown field")
        self.assertIn("scene.ron:3:5", str(e.exception))

    def test_query_line(self):
        d = R.parse_query("1000000 rays, 734120 hits in 0.800 s end to end (1.25 Mrays/s; chunks of 65536)")
        self.assertEqual((d["rays"], d["hits"]), (1000000, 734120))
        self.assertAlmostEqual(d["e2e_mrays"], 1.25, places=12)
        self.assertNotIn("trace_mrays", d)
        d = R.parse_query("1000000 rays, 5 hits in 2.000 s end to end, trace 0.500 s (2.00 Mrays/s)")
        self.assertAlmostEqual(d["trace_mrays"], 2.0, places=12)
        with self.assertRaises(ValueError):
            R.parse_query("nothing here")

    def test_open3d_lines(self):
        text = ("open3d 0.20.0 | 1280x720 rays\n"
                "level 4: 5120 tris, build s 0.0050, 1T Mrays/s 9.81 [9.10, 10.20], 2T Mrays/s 18.20 [17.10, 18.90], "
                "hits 343793, sum t 12345.678901\n"
                "level 8: 1310720 tris, build s 0.3100, 1T Mrays/s 6.50 [6.00, 7.00], 2T Mrays/s 12.40 [11.00, 13.00], "
                "hits 345393, sum t 1.0\n")
        got = R.parse_open3d(text)
        self.assertEqual(sorted(got), [4, 8])
        self.assertEqual(got[4], {"tris": 5120, "build_s": 0.005, "mrays1": 9.81, "mrays2": 18.2, "hits": 343793})
        self.assertEqual(got[8]["build_s"], 0.31)

    def test_result_line_takes_the_last(self):
        text = 'RESULT {"a": 1}\nnoise\nRESULT {"a": 2, "b": [1.5]}\n'
        self.assertEqual(R.parse_result_line(text), {"a": 2, "b": [1.5]})
        with self.assertRaises(ValueError):
            R.parse_result_line("Traceback ...")


class Numbers(unittest.TestCase):
    def test_median_and_ratio(self):
        self.assertEqual(R.median([5.0, 1.0, 3.0]), 3.0)
        self.assertEqual(R.median([4.0, 1.0, 3.0, 2.0]), 2.5)
        self.assertEqual(R.ratio(3.0, 2.0), 1.5)
        self.assertEqual(R.ratio(NA("x"), 2.0), NA("x"))
        self.assertEqual(R.ratio(1.0, NA("y")), NA("y"))
        self.assertIsInstance(R.ratio(1.0, 0.0), NA)

    def test_json_keeps_reasons(self):
        s = json.dumps(R.to_json({"a": NA("not installed"), "b": [1.0, float("inf")]}))
        self.assertEqual(json.loads(s), {"a": {"na": "not installed"}, "b": [1.0, "inf"]})


def figs():
    return {
        "quadrics": {"zeroset_aov": 30.0, "zeroset_depth": 40.0, "zeroset_default": 20.0, "zeroset_aov_1t": 16.0,
                     "mitsuba_render": 25.0, "mitsuba_rays": 31.0, "mitsuba_prelim": 40.0},
        "spheres1k": {"zeroset_aov": 10.0, "zeroset_depth": 9.0, "zeroset_default": 8.0, "zeroset_aov_1t": 5.5,
                      "mitsuba_render": NA("mitsuba not installed"), "mitsuba_rays": NA("mitsuba not installed"),
                      "mitsuba_prelim": NA("mitsuba not installed")},
        "mesh8": {"zeroset_aov": 14.0, "zeroset_depth": 15.0, "zeroset_default": 12.0, "zeroset_aov_1t": 7.0,
                  "embree": 13.2, "open3d": 13.6},
    }


class Floors(unittest.TestCase):
    def verdicts(self, extra):
        return {n: v for n, v, _ in R.floors(figs(), extra)}

    def test_verdicts(self):
        v = self.verdicts({"build": {"zeroset_bvh_s": 0.75, "zeroset_load_bvh_s": 4.0, "embree_s": 0.5},
                           "bytes_per_tri": 118.5,
                           "baseline_default": {"quadrics": 10.0, "spheres1k": 4.1, "mesh8": 6.0},
                           "query": {"mesh8": {"sorted": 5.0, "single": 5.0}}})
        # 30 ≥ 25, 30 < 31, 40 ≥ 40 (equal passes "≥ 1.0×")
        self.assertEqual(v["quadrics: AOV render ≥ 1.0× Mitsuba 3 LLVM AOV render"], "PASS")
        self.assertEqual(v["quadrics: AOV render ≥ 1.0× Mitsuba 3 LLVM ray_intersect (t + shading normal)"], "FAIL")
        self.assertEqual(v["quadrics: Depth-only render ≥ 1.0× Mitsuba ray_intersect_preliminary (t only)"], "PASS")
        # a peer that is missing is n/a, never PASS
        self.assertEqual(v["spheres1k: AOV render ≥ 1.0× Mitsuba 3 LLVM AOV render"], "n/a")
        self.assertEqual(v["mesh8: AOV render ≥ 1.0× Embree rtcIntersect1"], "PASS")   # 14 ≥ 13.2
        self.assertEqual(v["mesh8: AOV render ≥ 1.0× Open3D cast_rays"], "PASS")        # 14 ≥ 13.6
        self.assertEqual(v["mesh8: BVH build ≤ 1.5× Embree's"], "PASS")                # 0.75 ≤ 1.5 × 0.5
        self.assertEqual(v["mesh8: memory per triangle ≤ 118 B (today's)"], "FAIL")    # 118.5 > 118
        self.assertEqual(v["quadrics: default render ≥ 2× today's"], "PASS")             # 20 ≥ 2 × 10
        self.assertEqual(v["spheres1k: default render ≥ 2× today's"], "FAIL")            # 8 < 2 × 4.1
        self.assertEqual(v["mesh8: zeroset query, sorted-batch path beats the single-ray path"], "FAIL")  # a tie
        self.assertEqual(v["quadrics: scaling 1 → 2 threads ≥ 1.8× (AOV render)"], "PASS")   # 30/16 = 1.875
        self.assertEqual(v["spheres1k: scaling 1 → 2 threads ≥ 1.8× (AOV render)"], "PASS")  # 10/5.5 = 1.82
        self.assertEqual(v["mesh8: scaling 1 → 2 threads ≥ 1.8× (AOV render)"], "PASS")      # 14/7 = 2

    def test_build_falls_back_to_load_only_when_that_decides(self):
        v = self.verdicts({"build": {"zeroset_bvh_s": NA("no cargo"), "zeroset_load_bvh_s": 0.7, "embree_s": 0.5}})
        self.assertEqual(v["mesh8: BVH build ≤ 1.5× Embree's"], "PASS")  # 0.7 ≤ 0.75 even with PLY reading
        v = self.verdicts({"build": {"zeroset_bvh_s": NA("no cargo"), "zeroset_load_bvh_s": 4.0, "embree_s": 0.3}})
        self.assertEqual(v["mesh8: BVH build ≤ 1.5× Embree's"], "n/a")   # 4.0 s includes parsing: undecided
        v = self.verdicts({"build": {"zeroset_bvh_s": 0.9, "zeroset_load_bvh_s": 4.0, "embree_s": 0.3}})
        self.assertEqual(v["mesh8: BVH build ≤ 1.5× Embree's"], "FAIL")

    def test_hit_counts(self):
        v = self.verdicts({"hits": {"mesh4": {"zeroset": 343793, "embree": 343793},
                                    "mesh6": {"zeroset": 345297, "embree": 345298},
                                    "mesh8": {"zeroset": 345393, "embree": NA("embreex not installed")}}})
        self.assertEqual(v["mesh4: (must not regress) hit count identical to Embree's on its camera rays"], "PASS")
        self.assertEqual(v["mesh6: (must not regress) hit count identical to Embree's on its camera rays"], "FAIL")
        self.assertEqual(v["mesh8: (must not regress) hit count identical to Embree's on its camera rays"], "n/a")

    def test_no_baseline_is_not_measured(self):
        v = self.verdicts({"baseline_default": NA("give --baseline-zeroset")})
        self.assertEqual(v["mesh8: default render ≥ 2× today's"], "n/a")


class FloorsTable(unittest.TestCase):
    def test_na_rows_of_one_reason_merge_and_counts_add_up(self):
        rows = [("quadrics: default render ≥ 2× today's", "n/a", "no baseline"),
                ("mesh8: default render ≥ 2× today's", "n/a", "no baseline"),
                ("quadrics: scaling", "FAIL", "1.0×"),
                ("mesh8: scaling", "PASS", "2.0×"),
                ("mesh4: AOV render ≥ 1.0× Open3D cast_rays", "n/a", "open3d not installed")]
        t = R.floors_markdown(rows)
        self.assertIn("| quadrics, mesh8: default render ≥ 2× today's | **n/a** | no baseline |", t)
        self.assertIn("| quadrics: scaling | **FAIL** |", t)
        self.assertIn("| mesh4: AOV render ≥ 1.0× Open3D cast_rays | **n/a** | open3d not installed |", t)
        self.assertTrue(t.endswith("1 PASS, 1 FAIL, 3 n/a (of 5 checks)"))


class Table(unittest.TestCase):
    def test_ratios_in_the_table(self):
        t = R.main_table(figs(), 2)
        rows = {l.split("|")[1].strip(): l for l in t.splitlines()[2:]}
        self.assertIn("25.0 (1.20×)", rows["quadrics"])       # 30 / 25
        self.assertIn("31.0 (0.97×)", rows["quadrics"])       # 30 / 31
        self.assertIn("40.0 (1.00×)", rows["quadrics"])       # Depth 40 / prelim 40
        self.assertIn("16.0 → 30.0 (1.88×)", rows["quadrics"])
        self.assertIn("0.97 (vs Mitsuba 3 LLVM ray_intersect)", rows["quadrics"])  # fastest AOV peer: 31
        self.assertIn("1.03 (vs Open3D cast_rays)", rows["mesh8"])        # 14 / 13.6
        self.assertIn("| n/a |", rows["spheres1k"])
        self.assertTrue(any("mitsuba not installed" in r for r in R.missing_reasons(figs())))


if __name__ == "__main__":
    unittest.main()
