//! The Embree and Mitsuba 3 harnesses of `../shared/anchors/` (Python), run in the same session
//! when their packages import; skipped with a message otherwise. parry3d runs in-process
//! (`cases.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// A harness's outcome: a title and the lines to show (or why it was skipped).
#[derive(Clone, Debug)]
pub struct External {
    pub name: String,
    pub command: String,
    pub lines: Vec<String>,
    pub seconds: f64,
}

fn anchors() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/anchors")
}

fn importable(module: &str) -> bool {
    Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `python3 args…` in `dir` under `timeout`, returning (success, stdout, stderr).
fn python(dir: &Path, args: &[&str], timeout_s: u32) -> (bool, String, String) {
    match Command::new("timeout")
        .arg(timeout_s.to_string())
        .arg("python3")
        .args(args)
        .current_dir(dir)
        .output()
    {
        Ok(o) => (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        ),
        Err(e) => (false, String::new(), e.to_string()),
    }
}

fn tail(s: &str, n: usize) -> Vec<String> {
    let lines: Vec<&str> = s.lines().filter(|l| !l.trim().is_empty()).collect();
    lines[lines.len().saturating_sub(n)..]
        .iter()
        .map(|l| (*l).to_owned())
        .collect()
}

/// Pulls `"key": number` out of a RESULT JSON line.
fn json_number(line: &str, key: &str) -> Option<f64> {
    let at = line.find(&format!("\"{key}\""))? + key.len() + 2;
    let rest = line[at..].trim_start_matches([':', ' ']);
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    rest[..end].trim().parse().ok()
}

fn embree() -> External {
    let start = Instant::now();
    let command = "python3 ../shared/bench/gen.py --mesh /tmp/mesh4.ply 4 && cd ../shared/anchors/embree && python3 bench_embreex.py --levels 4 --runs 5 --build-runs 3".to_owned();
    let mut out = External {
        name: "Embree 4 (embreex), displaced icosphere level 4 (5,120 triangles), 1280×720 primary rays".into(),
        command,
        lines: Vec::new(),
        seconds: 0.0,
    };
    if !(importable("embreex") && importable("trimesh") && importable("numpy")) {
        out.lines
            .push("skipped: `import embreex, trimesh, numpy` failed (pip install embreex numpy trimesh)".into());
        return out;
    }
    let bench = anchors().join("../bench");
    if !Path::new("/tmp/mesh4.ply").exists() {
        let (ok, _, err) = python(&bench, &["gen.py", "--mesh", "/tmp/mesh4.ply", "4"], 120);
        if !ok {
            out.lines
                .push(format!("skipped: mesh generation failed: {}", tail(&err, 1).join(" ")));
            return out;
        }
    }
    let (ok, stdout, stderr) = python(
        &anchors().join("embree"),
        &["bench_embreex.py", "--levels", "4", "--runs", "5", "--build-runs", "3"],
        180,
    );
    if ok {
        out.lines = stdout
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(str::to_owned)
            .collect();
    } else {
        out.lines.push("failed:".into());
        out.lines.extend(tail(&stderr, 3));
    }
    out.seconds = start.elapsed().as_secs_f64();
    out
}

fn mitsuba() -> Vec<External> {
    let mut v = Vec::new();
    if !importable("mitsuba") {
        v.push(External {
            name: "Mitsuba 3".into(),
            command: "python3 ../shared/anchors/mitsuba/run_mitsuba.py …".into(),
            lines: vec!["skipped: `import mitsuba` failed (pip install mitsuba numpy)".into()],
            seconds: 0.0,
        });
        return v;
    }
    for (scene, mode, variant) in [
        ("quadrics", "rays", "llvm_ad_rgb"),
        ("quadrics", "render", "scalar_rgb"),
        ("spheres1k", "rays", "llvm_ad_rgb"),
    ] {
        let start = Instant::now();
        let args = [
            "run_mitsuba.py",
            mode,
            "--scene",
            scene,
            "--variant",
            variant,
            "--runs",
            "3",
        ];
        let (ok, stdout, stderr) = python(&anchors().join("mitsuba"), &args, 150);
        let mut lines = Vec::new();
        if let Some(result) = stdout.lines().find(|l| l.starts_with("RESULT")) {
            let mrays = json_number(result, "mrays_per_s_median");
            match mrays {
                Some(m) => lines.push(format!("{m:.2} Mrays/s (median of 3, 1280×720 pixel-centre rays)")),
                None => lines.push(result.chars().take(400).collect()),
            }
        } else {
            lines.push(format!(
                "{}: {}",
                if ok { "no RESULT line" } else { "failed" },
                tail(&stderr, 2).join(" | ")
            ));
        }
        v.push(External {
            name: format!("Mitsuba 3 `{mode}` {scene} ({variant})"),
            command: format!("cd ../shared/anchors/mitsuba && python3 {}", args.join(" ")),
            lines,
            seconds: start.elapsed().as_secs_f64(),
        });
    }
    v
}

/// Runs both harnesses.
pub fn run_external() -> Vec<External> {
    let mut v = vec![embree()];
    v.extend(mitsuba());
    v
}
