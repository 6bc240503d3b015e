//! Messages about valid input and undecided rays, printed to stderr by the CLI.
//!
//! - **Load warnings** ([`crate::scene::Scene::warnings`]): degenerate triangles left out, a
//!   `Function` that may be undefined in parts of its box, a `lipschitz` field no longer needed.
//! - **Uncertain rays** (`zeroset_primitives::isolation`): rays whose first root of a `Function`
//!   could not be decided exactly (a tangent touch reported as a hit, a spent budget reported as
//!   a miss, pieces where Φ may be undefined). They are counted, never silently dropped.

use crate::scene::Scene;
use zeroset_primitives::{uncertain_counts, UncertainCounts};

/// Prints the scene's load warnings, one line each.
pub fn print_load_warnings(scene: &Scene) {
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
}

/// The uncertain-ray counts since `before` (taken with [`uncertain_counts`] before tracing).
#[must_use]
pub fn uncertain_since(before: UncertainCounts) -> UncertainCounts {
    let now = uncertain_counts();
    UncertainCounts {
        tangent: now.tangent - before.tangent,
        exhausted: now.exhausted - before.exhausted,
        undefined: now.undefined - before.undefined,
    }
}

/// A one-line warning for non-zero counts, `None` when every ray was decided exactly.
#[must_use]
pub fn uncertain_message(counts: UncertainCounts) -> Option<String> {
    if counts.is_empty() {
        return None;
    }
    Some(format!(
        "warning: Function roots not decided exactly: {} rays touch Φ = 0 within the tolerance \
         without a proven crossing (reported as hits: tangent rays, double roots), {} rays ran out \
         of their budget (reported as misses; raise `budget`), {} rays met pieces where Φ may be \
         undefined (skipped)",
        counts.tangent, counts.exhausted, counts.undefined
    ))
}
