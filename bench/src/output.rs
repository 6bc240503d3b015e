//! The report: markdown (stdout and `results.md`) and CSV files.

use crate::cases::{CaseOptions, Row};
use crate::peers::External;
use crate::scenes::SceneRow;
use crate::torus::TorusResult;
use std::fmt::Write as _;
use std::path::Path;

pub struct Report {
    pub rays: usize,
    pub passes: usize,
    pub generic_cap: u32,
    pub seed: u64,
    pub scene_runs: usize,
    pub rows: Vec<Row>,
    pub torus: Option<TorusResult>,
    pub scenes: Vec<SceneRow>,
    pub external: Vec<External>,
    pub elapsed_s: f64,
}

fn e(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x:.1e}")
    }
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".into())
}

impl Report {
    pub fn new(opt: &CaseOptions, scene_runs: usize) -> Self {
        Report {
            rays: opt.rays,
            passes: opt.passes,
            generic_cap: opt.generic_cap,
            seed: opt.seed,
            scene_runs,
            rows: Vec::new(),
            torus: None,
            scenes: Vec::new(),
            external: Vec::new(),
            elapsed_s: 0.0,
        }
    }

    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
        let _ = writeln!(s, "# zeroset: speed against error\n");
        let _ = writeln!(
            s,
            "{cores} cores, load average at the end {} (figures taken on a loaded machine are noisy); \
             {:.0} s in all. Rays per primitive: {} (seed {}), 70 % random through the bounds (hits and misses), \
             30 % hard (grazing within ~1e-7 of tangency, edges, rims, vertices, apex); every ray is f32-exact, \
             the same for every method; query range t ∈ [0, 1e4]. ns/ray: median of {} passes over all rays, \
             one thread, intersection + normal; the generic finder may spend {} Φ evaluations on a ray (more is a miss). Errors against a double-double reference: relative t error over \
             rays both hit; normal angle away from edges and rims (relative margin > 1e-6); disagree = rays where \
             the method and the reference differ on hit/miss.\n",
            load(),
            self.elapsed_s,
            self.rays,
            self.seed,
            self.passes,
            self.generic_cap
        );
        if !self.rows.is_empty() {
            let _ = writeln!(s, "## Primitives (★ = zeroset's default)\n");
            let _ = writeln!(
                s,
                "| primitive | method | prec | ns/ray | max rel t err | median rel t err | max normal err ° | disagree | NaN |"
            );
            let _ = writeln!(s, "|---|---|---|---:|---:|---:|---:|---:|---:|");
            for r in &self.rows {
                let m = &r.m;
                let _ = writeln!(
                    s,
                    "| {} | {}{} | {} | {:.1} | {} | {} | {} | {} | {} |",
                    r.primitive,
                    if r.default { "★ " } else { "" },
                    r.method,
                    r.precision,
                    m.ns_median,
                    e(m.max_rel_t),
                    e(m.median_rel_t),
                    e(m.max_normal_deg),
                    m.disagreements,
                    m.nans
                );
            }
            s.push('\n');
            s.push_str(&self.floors());
        }
        if let Some(t) = &self.torus {
            s.push_str(&torus_markdown(t));
        }
        if !self.scenes.is_empty() {
            let _ = writeln!(
                s,
                "## Whole scenes (`scenes/bench/`, 1280×720 primary rays, default AOVs, median of {} renders)\n",
                self.scene_runs
            );
            let _ = writeln!(
                s,
                "| scene | objects | load + BVH ms | threads | Mrays/s median [min, max] | peak RSS MiB | distance AOV (f32) max / median rel err | f64 t max / median rel err | hit/object disagreements |"
            );
            let _ = writeln!(s, "|---|---:|---:|---:|---|---:|---|---|---:|");
            for r in &self.scenes {
                for (threads, _t, mr, lo, hi) in &r.timings {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {:.1} | {} | {:.2} [{:.2}, {:.2}] | {:.0} | {} / {} | {} / {} | {} of {} |",
                        r.scene,
                        r.objects,
                        r.load_ms,
                        threads,
                        mr,
                        lo,
                        hi,
                        r.peak_rss_mib,
                        e(r.max_rel_aov),
                        e(r.median_rel_aov),
                        e(r.max_rel_f64),
                        e(r.median_rel_f64),
                        r.disagree,
                        r.checked
                    );
                }
            }
            s.push('\n');
            for r in self.scenes.iter().filter(|r| !r.note.is_empty()) {
                let _ = writeln!(s, "- {}: {}", r.scene, r.note);
            }
            let _ = writeln!(
                s,
                "\nReference figures, same scenes, a 2-core machine of this kind, 2 threads (`../shared/anchors/README.md`): \
                 spheres1k POV-Ray 5.9, Mitsuba LLVM AOV 13.1, Embree 21.0 Mrays/s; quadrics POV-Ray 10.1, Mitsuba LLVM AOV 45.5, \
                 Mitsuba scalar 0.7 Mrays/s. The distance AOV is stored as f32, so its error floor is ~6e-8.\n"
            );
        }
        if !self.external.is_empty() {
            let _ = writeln!(s, "## Peers run in this session (Python harnesses)\n");
            for x in &self.external {
                let _ = writeln!(s, "**{}** ({:.0} s) — `{}`\n", x.name, x.seconds, x.command);
                let _ = writeln!(s, "```");
                for l in &x.lines {
                    let _ = writeln!(s, "{l}");
                }
                let _ = writeln!(s, "```\n");
            }
        }
        s
    }

    /// The issue's floors against parry3d, per primitive parry has.
    fn floors(&self) -> String {
        let mut s = String::from(
            "### Floors against parry3d (same rays, same run)\n\n\
             | primitive | default ns/ray | parry f32 ns/ray | as fast as parry f32 | default max rel t / disagree | parry f64 max rel t / disagree | as accurate as parry f64 |\n\
             |---|---:|---:|---|---|---|---|\n",
        );
        let mut primitives: Vec<&str> = self.rows.iter().map(|r| r.primitive).collect();
        primitives.dedup();
        for p in primitives {
            let find = |f: &dyn Fn(&Row) -> bool| self.rows.iter().find(|r| r.primitive == p && f(r));
            let (Some(d), Some(p32), Some(p64)) = (
                find(&|r| r.default),
                find(&|r| r.family == "parry3d" && r.precision == "f32"),
                find(&|r| r.family == "parry3d" && r.precision == "f64"),
            ) else {
                continue;
            };
            let fast = d.m.ns_median <= p32.m.ns_median;
            let accurate = d.m.max_rel_t <= p64.m.max_rel_t && d.m.disagreements <= p64.m.disagreements;
            let _ = writeln!(
                s,
                "| {p} | {:.1} | {:.1} | {} | {} / {} | {} / {} | {} |",
                d.m.ns_median,
                p32.m.ns_median,
                if fast { "yes" } else { "**no**" },
                e(d.m.max_rel_t),
                d.m.disagreements,
                e(p64.m.max_rel_t),
                p64.m.disagreements,
                if accurate { "yes" } else { "**no**" }
            );
        }
        s.push('\n');
        s
    }

    pub fn write(&self, dir: &Path) {
        let _ = std::fs::write(dir.join("results.md"), self.markdown());
        let mut csv = String::from(
            "primitive,method,family,precision,default,rays,reference_hits,ns_per_ray_median,ns_per_ray_min,ns_per_ray_max,max_rel_t_err,median_rel_t_err,max_normal_err_deg,hit_miss_disagreements,nan_count\n",
        );
        for r in &self.rows {
            let m = &r.m;
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:e},{:e},{:e},{},{}",
                r.primitive,
                r.method,
                r.family,
                r.precision,
                r.default,
                m.rays,
                m.ref_hits,
                m.ns_median,
                m.ns_min,
                m.ns_max,
                m.max_rel_t,
                m.median_rel_t,
                m.max_normal_deg,
                m.disagreements,
                m.nans
            );
        }
        let _ = std::fs::write(dir.join("primitives.csv"), csv);
        if let Some(t) = &self.torus {
            let mut csv = String::from(
                "method,tolerance,declared_lipschitz,rays,ns_per_ray_median,max_abs_t_err,max_rel_t_err,hit_miss_disagreements,holes,violations_reported\n",
            );
            for r in &t.rows {
                let _ = writeln!(
                    csv,
                    "{},{},{},{},{:.3},{:e},{:e},{},{},{}",
                    r.method,
                    r.tolerance.map_or(String::new(), |x| format!("{x:e}")),
                    r.declared_lipschitz.map_or(String::new(), |x| x.to_string()),
                    t.rays,
                    r.m.ns_median,
                    r.max_abs_t,
                    r.m.max_rel_t,
                    r.m.disagreements,
                    r.holes,
                    r.violations
                );
            }
            let _ = std::fs::write(dir.join("torus.csv"), csv);
        }
        if !self.scenes.is_empty() {
            let mut csv = String::from(
                "scene,objects,pixels,load_bvh_ms,threads,median_s,mrays_per_s_median,mrays_per_s_min,mrays_per_s_max,peak_rss_mib,max_rel_err_distance_aov,median_rel_err_distance_aov,max_rel_err_f64_t,median_rel_err_f64_t,disagreements,checked_pixels\n",
            );
            for r in &self.scenes {
                for (threads, t, mr, lo, hi) in &r.timings {
                    let _ = writeln!(
                        csv,
                        "{},{},{},{:.2},{},{:.5},{:.3},{:.3},{:.3},{:.1},{:e},{:e},{:e},{:e},{},{}",
                        r.scene,
                        r.objects,
                        r.pixels,
                        r.load_ms,
                        threads,
                        t,
                        mr,
                        lo,
                        hi,
                        r.peak_rss_mib,
                        r.max_rel_aov,
                        r.median_rel_aov,
                        r.max_rel_f64,
                        r.median_rel_f64,
                        r.disagree,
                        r.checked
                    );
                }
            }
            let _ = std::fs::write(dir.join("scenes.csv"), csv);
        }
    }
}

fn torus_markdown(t: &TorusResult) -> String {
    let mut s = format!(
        "## Generic implicit intersector: torus R = 1, r = 0.35 ({} random rays through its bounds)\n\n\
         | method | ns/ray | max abs t err | max rel t err | disagree | holes (missed, depth > tol) | rays reporting a violated bound (interval: flagged uncertain) |\n\
         |---|---:|---:|---:|---:|---:|---:|\n",
        t.rays
    );
    for r in &t.rows {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {} | {} | {} | {} | {} |",
            r.method,
            r.m.ns_median,
            e(r.max_abs_t),
            e(r.m.max_rel_t),
            r.m.disagreements,
            r.holes,
            r.violations
        );
    }
    let closed = t.closed();
    let _ = writeln!(s, "\nFloors (POV-Ray isosurface: 9.8e-7 at accuracy 1e-6, 3.2× its analytic torus; ~780 holes in 40,000 rays with a too-small bound, only a warning):\n");
    match t.generic_at_1e6() {
        Some(g) => {
            let ratio = g.m.ns_median / closed.m.ns_median;
            let _ = writeln!(
                s,
                "- max |t err| ≤ 1e-6 first reached by `{}`: {} at {:.2}× the closed form's cost ({:.1} vs {:.1} ns/ray): {}",
                g.method,
                e(g.max_abs_t),
                ratio,
                g.m.ns_median,
                closed.m.ns_median,
                if ratio <= 3.0 { "met (≤ 3×)" } else { "**not met** (> 3×)" }
            );
        }
        None => {
            let _ = writeln!(s, "- no tolerance reached max |t err| ≤ 1e-6: **not met**");
        }
    }
    let true_holes: usize = t
        .rows
        .iter()
        .filter(|r| r.declared_lipschitz == Some(1.0))
        .map(|r| r.holes)
        .sum();
    let _ = writeln!(
        s,
        "- true bound (L = 1), all tolerances: {true_holes} holes: {}",
        if true_holes == 0 { "met" } else { "**not met**" }
    );
    if let Some(w) = t.rows.iter().find(|r| r.declared_lipschitz == Some(0.25)) {
        let _ = writeln!(
            s,
            "- wrong bound (L = 0.25): {} holes, violation reported on {} rays: {}\n",
            w.holes,
            w.violations,
            if w.violations > 0 {
                "detected and reported (met)"
            } else {
                "**not detected**"
            }
        );
    }
    s
}
