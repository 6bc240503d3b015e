"""Pure helpers of bench/throughput.py: parsing zeroset's summary lines, medians, the floors of
issue #11 and the markdown table. No process is started here, so the unit tests
(`python3 -m unittest discover -s bench/throughput`) check this logic on fixed inputs.

A figure is a float (Mrays/s, seconds, bytes) or an `NA`: a missing figure that carries the
reason it is missing (peer not installed, harness failed, ...), printed as "n/a (reason)".
"""
import math
import re
import statistics

# ---------------------------------------------------------------------------------------------
# missing figures
# ---------------------------------------------------------------------------------------------


class NA:
    """A figure that could not be measured, with the reason."""

    def __init__(self, reason):
        self.reason = str(reason)

    def __repr__(self):
        return f"NA({self.reason!r})"

    def __eq__(self, other):
        return isinstance(other, NA) and other.reason == self.reason

    def to_json(self):
        return {"na": self.reason}


def is_num(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def median(xs):
    """Median of a non-empty list of numbers (the mean of the middle two for an even count)."""
    if not xs:
        raise ValueError("median of no values")
    return statistics.median(xs)


def ratio(a, b):
    """a / b, or an NA naming the missing side."""
    if isinstance(a, NA):
        return a
    if isinstance(b, NA):
        return b
    if a is None or b is None:
        return NA("not measured")
    if not (is_num(a) and is_num(b)) or b <= 0:
        return NA(f"cannot divide {a!r} by {b!r}")
    return a / b


# ---------------------------------------------------------------------------------------------
# zeroset's output lines
# ---------------------------------------------------------------------------------------------

# `rendered 1280x720 at 1 spp (6 objects) on 2 threads: trace 0.296 s (3.11 Mrays/s), wall 0.441 s
# (load+BVH 0.000 s, write 0.086 s; CPU 0.13 s)` (src/cli/render.rs)
RENDER_RE = re.compile(
    r"rendered (?P<w>\d+)x(?P<h>\d+) at (?P<spp>\d+) spp .*? on (?P<threads>\d+) threads: "
    r"trace (?P<trace_s>[0-9.]+) s \((?P<mrays>[0-9.]+) Mrays/s\), wall (?P<wall_s>[0-9.]+) s "
    r"\(load\+BVH (?P<load_s>[0-9.]+) s")

# `1000000 rays, 734120 hits in 1.234 s end to end (0.81 Mrays/s; chunks of 65536)`; a `trace X s`
# figure anywhere on the line is taken as the trace time if a later zeroset prints one.
QUERY_RE = re.compile(r"(?P<rays>\d+) rays, (?P<hits>\d+) hits in (?P<e2e_s>[0-9.]+) s end to end")
QUERY_TRACE_RE = re.compile(r"trace (?P<trace_s>[0-9.]+) s")


def parse_render(text):
    """The summary line of `zeroset render` as a dict of numbers; ValueError if absent."""
    m = RENDER_RE.search(text)
    if not m:
        raise ValueError("no 'rendered WxH ... trace S s (M Mrays/s), wall ... (load+BVH ...' line in: "
                         + text.strip()[-400:])
    d = {k: float(v) for k, v in m.groupdict().items()}
    for k in ("w", "h", "spp", "threads"):
        d[k] = int(d[k])
    return d


def parse_query(text):
    """The summary line of `zeroset query`: rays, hits, end-to-end seconds, Mrays/s, and the trace
    seconds where the line has them."""
    line = next((l for l in text.splitlines() if QUERY_RE.search(l)), None)
    if line is None:
        raise ValueError("no 'N rays, H hits in S s end to end' line in: " + text.strip()[-400:])
    m = QUERY_RE.search(line)
    d = {"rays": int(m["rays"]), "hits": int(m["hits"]), "e2e_s": float(m["e2e_s"])}
    d["e2e_mrays"] = d["rays"] / max(d["e2e_s"], 1e-9) / 1e6
    t = QUERY_TRACE_RE.search(line)
    if t:
        d["trace_s"] = float(t["trace_s"])
        d["trace_mrays"] = d["rays"] / max(d["trace_s"], 1e-9) / 1e6
    return d


# Open3D harness: `level 4: 5120 tris, build s 0.0050, 1T Mrays/s 9.81 [9.1, 10.2], 2T Mrays/s
# 18.20 [17.1, 18.9], hits 343793, sum t 12345.678901`
OPEN3D_RE = re.compile(
    r"level (?P<level>\d+): (?P<tris>\d+) tris, build s (?P<build_s>[0-9.eE+-]+), "
    r"1T Mrays/s (?P<mrays1>[0-9.]+) \[[^]]*\], 2T Mrays/s (?P<mrays2>[0-9.]+) \[[^]]*\], "
    r"hits (?P<hits>\d+)")


def parse_open3d(text):
    """{level: {tris, build_s, mrays1, mrays2, hits}} from bench_open3d.py's output."""
    out = {}
    for m in OPEN3D_RE.finditer(text):
        out[int(m["level"])] = {"tris": int(m["tris"]), "build_s": float(m["build_s"]),
                                "mrays1": float(m["mrays1"]), "mrays2": float(m["mrays2"]),
                                "hits": int(m["hits"])}
    return out


def parse_result_line(text):
    """The JSON after `RESULT ` (run_mitsuba.py's last word); ValueError if absent."""
    import json
    for line in reversed(text.splitlines()):
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    raise ValueError("no RESULT line in: " + text.strip()[-600:])


# ---------------------------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------------------------

MESH_SCENES = ("mesh4", "mesh6", "mesh8")
QUADRIC_SCENES = ("quadrics", "spheres1k")
ALL_SCENES = QUADRIC_SCENES + MESH_SCENES

# peers compared with zeroset's AOV render (t + normal or more); Depth-only is compared with
# Mitsuba's ray_intersect_preliminary (t only) on its own
AOV_PEERS = (("mitsuba_render", "Mitsuba 3 LLVM AOV render"),
             ("mitsuba_rays", "Mitsuba 3 LLVM ray_intersect (t + sh. normal)"),
             ("embree", "Embree rtcIntersect1"),
             ("open3d", "Open3D cast_rays"))


def fmt(x, digits=1):
    if isinstance(x, NA):
        return "n/a"
    if x is None:
        return "–"
    if not is_num(x):
        return str(x)
    return f"{x:.{digits}f}"


def fmt_ratio(r):
    if isinstance(r, NA) or r is None:
        return "–"
    return f"{r:.2f}×"


def fastest_peer(fig):
    """(name, Mrays/s) of the fastest AOV peer measured for one scene, or None."""
    best = None
    for key, _ in AOV_PEERS:
        v = fig.get(key)
        if is_num(v) and (best is None or v > best[1]):
            best = (key, v)
    return best


def peer_cell(value, ours):
    if isinstance(value, NA):
        return "n/a"
    if value is None:
        return "–"
    r = ratio(ours, value)
    return f"{fmt(value)} ({fmt_ratio(r)})" if is_num(r) else fmt(value)


def main_table(figs, threads):
    """The markdown table: per scene, each system's Mrays/s; in brackets zeroset's ratio to that
    peer (AOV render against the AOV peers, Depth-only against ray_intersect_preliminary)."""
    head = (f"| scene | zeroset AOV render (Depth, Normal, Alpha) | zeroset Depth-only | zeroset default render "
            f"| zeroset AOV 1T → {threads}T | Mitsuba 3 LLVM AOV render | Mitsuba ray_intersect t + normal "
            f"| Mitsuba ray_intersect_preliminary t | Embree rtcIntersect1 | Open3D cast_rays | ratio to fastest peer |")
    lines = [head, "|" + "---|" * 11]
    for scene, f in figs.items():
        aov, depth = f.get("zeroset_aov"), f.get("zeroset_depth")
        one = f.get("zeroset_aov_1t")
        scaling = ratio(aov, one)
        fast = fastest_peer(f)
        fast_cell = "–"
        if fast is not None and is_num(aov):
            fast_cell = f"{aov / fast[1]:.2f} (vs {dict(AOV_PEERS)[fast[0]].split(' (')[0]})"
        lines.append("| " + " | ".join([
            scene, fmt(aov), fmt(depth), fmt(f.get("zeroset_default")),
            f"{fmt(one)} → {fmt(aov)} ({fmt_ratio(scaling)})" if is_num(scaling) else "–",
            peer_cell(f.get("mitsuba_render"), aov),
            peer_cell(f.get("mitsuba_rays"), aov),
            peer_cell(f.get("mitsuba_prelim"), depth),
            peer_cell(f.get("embree"), aov),
            peer_cell(f.get("open3d"), aov),
            fast_cell]) + " |")
    return "\n".join(lines)


def missing_reasons(figs):
    """One line per distinct (system, reason) of the n/a cells."""
    seen = {}
    for scene, f in figs.items():
        for k, v in f.items():
            if isinstance(v, NA):
                seen.setdefault((k, v.reason), []).append(scene)
    return [f"- n/a {k} ({', '.join(s)}): {r}" for (k, r), s in seen.items()]


# ---------------------------------------------------------------------------------------------
# floors (issue #11, "Floors")
# ---------------------------------------------------------------------------------------------

PASS, FAIL, NOTMEASURED = "PASS", "FAIL", "n/a"


def verdict(ok):
    return PASS if ok else FAIL


def at_least(ours, theirs, factor=1.0):
    """(verdict, ratio) for `ours >= factor * theirs`; n/a when either side is missing."""
    r = ratio(ours, theirs)
    if isinstance(r, NA):
        return NOTMEASURED, r
    return verdict(r >= factor), r


def floors(figs, extra, threads=2):
    """[(floor, verdict, detail)] for each floor of issue #11.

    figs: {scene: {figure: value}} as in main_table; extra: {
      "build": {"zeroset_bvh_s", "zeroset_load_bvh_s", "embree_s"}, "bytes_per_tri",
      "baseline_default": {scene: Mrays/s of today's zeroset} or NA,
      "query": {scene: {"sorted": Mrays/s, "single": Mrays/s} or NA},
      "hits": {scene: {"zeroset": count or NA, "embree": count or NA}}}.
    """
    out = []

    def add(name, v, detail):
        out.append((name, v, detail))

    for scene in QUADRIC_SCENES:
        f = figs.get(scene)
        if f is None:
            continue
        for key, label in (("mitsuba_render", "Mitsuba 3 LLVM AOV render"),
                           ("mitsuba_rays", "Mitsuba 3 LLVM ray_intersect (t + shading normal)")):
            v, r = at_least(f.get("zeroset_aov"), f.get(key))
            add(f"{scene}: AOV render ≥ 1.0× {label}", v, _detail(f.get("zeroset_aov"), f.get(key), r))
        v, r = at_least(f.get("zeroset_depth"), f.get("mitsuba_prelim"))
        add(f"{scene}: Depth-only render ≥ 1.0× Mitsuba ray_intersect_preliminary (t only)", v,
            _detail(f.get("zeroset_depth"), f.get("mitsuba_prelim"), r))
    for scene in MESH_SCENES:
        f = figs.get(scene)
        if f is None:
            continue
        for key, label in (("embree", "Embree rtcIntersect1"), ("open3d", "Open3D cast_rays")):
            v, r = at_least(f.get("zeroset_aov"), f.get(key))
            add(f"{scene}: AOV render ≥ 1.0× {label}", v, _detail(f.get("zeroset_aov"), f.get(key), r))

    if "mesh8" in figs:
        b = extra.get("build", {})
        bvh, load, emb = b.get("zeroset_bvh_s"), b.get("zeroset_load_bvh_s"), b.get("embree_s")
        name = "mesh8: BVH build ≤ 1.5× Embree's"
        if is_num(bvh) and is_num(emb):
            add(name, verdict(bvh <= 1.5 * emb), f"{bvh:.3f} s vs {emb:.3f} s = {bvh / emb:.2f}× (Mesh::new, cargo bench --bench mesh)")
        elif is_num(load) and is_num(emb) and load <= 1.5 * emb:
            add(name, PASS, f"even load+BVH (PLY reading included) {load:.3f} s ≤ 1.5 × {emb:.3f} s")
        else:
            why = bvh.reason if isinstance(bvh, NA) else "zeroset's BVH build alone not measured"
            if isinstance(emb, NA):
                why = emb.reason
            more = f"; load+BVH (PLY reading included) {load:.3f} s" if is_num(load) else ""
            more += f", Embree {emb:.3f} s" if is_num(emb) else ""
            add(name, NOTMEASURED, why + more)
        bpt = extra.get("bytes_per_tri")
        name = "mesh8: memory per triangle ≤ 118 B (today's)"
        if is_num(bpt):
            add(name, verdict(bpt <= 118.0), f"{bpt:.1f} B/triangle (Mesh::memory_bytes)")
        else:
            add(name, NOTMEASURED, bpt.reason if isinstance(bpt, NA) else "not measured")

    base = extra.get("baseline_default")
    for scene, f in figs.items():
        name = f"{scene}: default render ≥ 2× today's"
        if isinstance(base, NA) or base is None:
            add(name, NOTMEASURED, base.reason if isinstance(base, NA) else "no baseline")
            continue
        v, r = at_least(f.get("zeroset_default"), base.get(scene), 2.0)
        add(name, v, _detail(f.get("zeroset_default"), base.get(scene), r))

    for scene, q in (extra.get("query") or {}).items():
        name = f"{scene}: zeroset query, sorted-batch path beats the single-ray path"
        if isinstance(q, NA):
            add(name, NOTMEASURED, q.reason)
            continue
        v, r = at_least(q.get("sorted"), q.get("single"), 1.0)
        if v == PASS and is_num(r) and r == 1.0:
            v = FAIL  # "beat" is strict
        add(name, v, _detail(q.get("sorted"), q.get("single"), r))

    for scene, h in (extra.get("hits") or {}).items():
        name = f"{scene}: (must not regress) hit count identical to Embree's on its camera rays"
        ours, theirs = h.get("zeroset"), h.get("embree")
        if isinstance(ours, int) and isinstance(theirs, int):
            add(name, verdict(ours == theirs), f"zeroset query {ours}, Embree {theirs}")
        else:
            bad = ours if isinstance(ours, NA) else theirs
            add(name, NOTMEASURED, bad.reason if isinstance(bad, NA) else "not measured")

    for scene, f in figs.items():
        v, r = at_least(f.get("zeroset_aov"), f.get("zeroset_aov_1t"), 1.8)
        add(f"{scene}: scaling 1 → {threads} threads ≥ 1.8× (AOV render)", v,
            _detail(f.get("zeroset_aov"), f.get("zeroset_aov_1t"), r))
    return out


def _detail(a, b, r):
    if isinstance(r, NA):
        return r.reason
    return f"{fmt(a, 2)} vs {fmt(b, 2)} Mrays/s = {r:.2f}×"


def floors_markdown(rows):
    """The floors as a table; the n/a rows of one floor with one reason are merged across scenes
    (`quadrics, mesh8: default render ≥ 2× today's`), and a count of each verdict closes it."""
    merged, order = {}, []
    for n, v, d in rows:
        scene, _, floor = n.partition(": ")
        key = (floor, v, d) if v == NOTMEASURED and floor else (n, v, d)
        if key not in merged:
            merged[key] = []
            order.append(key)
        merged[key].append(scene)
    lines = ["| floor | verdict | figures |", "|---|---|---|"]
    for key in order:
        name, v, d = key
        if v == NOTMEASURED and name != merged[key][0]:  # merged by floor: name the scenes again
            name = f"{', '.join(merged[key])}: {name}"
        lines.append(f"| {name} | **{v}** | {d} |")
    counts = {x: sum(1 for _, v, _ in rows if v == x) for x in (PASS, FAIL, NOTMEASURED)}
    lines.append("")
    lines.append(f"{counts[PASS]} PASS, {counts[FAIL]} FAIL, {counts[NOTMEASURED]} n/a (of {len(rows)} checks)")
    return "\n".join(lines)


def to_json(x):
    """JSON-ready copy of nested dicts/lists holding NA values."""
    if isinstance(x, NA):
        return x.to_json()
    if isinstance(x, dict):
        return {str(k): to_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_json(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return x
