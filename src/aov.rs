//! Arbitrary output variables: what a render can write, and their EXR channel names.
//!
//! | AOV            | channels              | value on a hit                                      | on a miss |
//! |----------------|-----------------------|-----------------------------------------------------|-----------|
//! | `Beauty`       | `R, G, B`             | shaded colour (linear), premultiplied by `A`        | 0 (the background with `--background`) |
//! | `Alpha`        | `A`                   | 1                                                   | 0 |
//! | `Depth`        | `Z`                   | planar depth along the view axis (ray distance for the panoramic camera models, see [`crate::camera`]) | +∞ (or `--depth-miss`) |
//! | `Distance`     | `distance`            | ray distance `t` from the eye (unit-length rays)     | +∞ (or `--depth-miss`) |
//! | `Normal`       | `N.X, N.Y, N.Z`       | world-space unit ∇Φ normal, outward, not flipped: the **geometric** normal (a mesh's face normal) | 0 |
//! | `ShadingNormal` | `Ns.X, Ns.Y, Ns.Z`   | world-space **shading** normal (a mesh's interpolated vertex normals); equals `N` where a primitive has none | 0 |
//! | `Position`     | `P.X, P.Y, P.Z`       | world-space hit point                               | 0 |
//! | `CameraNormal` | `Nc.X, Nc.Y, Nc.Z`    | the normal in camera space (+x right, +y up, −z view) | 0 |
//! | `PrimitiveId`  | `id`                  | index of the object in the scene's `objects` list   | −1 |
//! | `Uv`           | `u, v`                | surface parameters (0 where a type has none)        | 0 |
//! | `Uncertain`    | `uncertain`           | 1 where a ray of the pixel (primary or shadow) ran out of the root finder's evaluation budget, so the pixel may be wrong; else 0 | same |
//!
//! **Several samples per pixel** (`sampling.spp > 1`, or moving objects) are resolved per AOV,
//! since only colour may be blended:
//!
//! | AOV | rule over the pixel's samples |
//! |---|---|
//! | `Beauty` | filter-weighted mean of the samples' colours, misses counting as black (premultiplied: `R, G, B` already carry the coverage `A`; with `--background` misses count as the background) |
//! | `Alpha` | coverage: filter-weighted fraction of samples that hit (with `Box`, hits / spp) |
//! | `Depth`, `Distance`, `Position` | all three from the **nearest** hit sample (smallest `Z`; the first of equals), never averaged across a silhouette |
//! | `PrimitiveId` | the object hit by the most samples; ties go to the one with the nearest sample |
//! | `Normal`, `CameraNormal`, `ShadingNormal` | mean over the samples that hit that object only, renormalised |
//! | `Uv` | mean over the same samples as the normal (not seam-aware) |
//! | `Uncertain` | 1 if any sample's rays ran out of budget |
//!
//! A pixel no sample hits gets the miss values. `Distance` is measured from the sample's lens
//! point (the eye for a pinhole); `Z` is planar depth from the eye (ray distance for the
//! panoramic camera models).

use serde::Deserialize;

/// One output variable (see the module table).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Deserialize, clap::ValueEnum)]
#[serde(deny_unknown_fields)]
#[value(rename_all = "PascalCase")]
pub enum Aov {
    /// Shaded colour `R, G, B`.
    Beauty,
    /// Coverage `A`.
    Alpha,
    /// Planar depth `Z`.
    Depth,
    /// Ray distance `distance`.
    Distance,
    /// World normal `N.X, N.Y, N.Z`.
    Normal,
    /// World position `P.X, P.Y, P.Z`.
    Position,
    /// Camera-space normal `Nc.X, Nc.Y, Nc.Z`.
    CameraNormal,
    /// Object index `id`.
    PrimitiveId,
    /// Surface parameters `u, v`.
    Uv,
    /// World shading normal `Ns.X, Ns.Y, Ns.Z` (the geometric normal where there is none).
    ShadingNormal,
    /// `uncertain`: 1 where the root finder's budget ran out for a ray of the pixel.
    Uncertain,
}

impl Aov {
    /// The default outputs: beauty, coverage, depth and normals.
    pub const DEFAULT: [Aov; 4] = [Aov::Beauty, Aov::Alpha, Aov::Depth, Aov::Normal];

    /// Every AOV, in the order of the module table (`--aov all`).
    pub const ALL: [Aov; 11] = [
        Aov::Beauty,
        Aov::Alpha,
        Aov::Depth,
        Aov::Distance,
        Aov::Normal,
        Aov::ShadingNormal,
        Aov::Position,
        Aov::CameraNormal,
        Aov::PrimitiveId,
        Aov::Uv,
        Aov::Uncertain,
    ];

    /// The AOVs a list of names asks for: names of [`Aov`] (any case, spaces around them
    /// allowed) or `all`; the error names the first unknown one and the choices.
    ///
    /// # Errors
    /// A name that is neither an AOV nor `all`.
    pub fn parse_list(names: &[String]) -> Result<Vec<Aov>, String> {
        let mut aovs = Vec::new();
        for name in names {
            if name.trim().eq_ignore_ascii_case("all") {
                aovs.extend(Aov::ALL);
                continue;
            }
            match <Aov as clap::ValueEnum>::from_str(name.trim(), true) {
                Ok(aov) => aovs.push(aov),
                Err(_) => {
                    let known: Vec<String> = Aov::ALL.iter().map(|a| format!("{a:?}")).collect();
                    return Err(format!("{name}: unknown AOV; use {} or all", known.join(", ")));
                }
            }
        }
        Ok(aovs)
    }

    /// EXR channel names, in order.
    #[must_use]
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Aov::Beauty => &["R", "G", "B"],
            Aov::Alpha => &["A"],
            Aov::Depth => &["Z"],
            Aov::Distance => &["distance"],
            Aov::Normal => &["N.X", "N.Y", "N.Z"],
            Aov::Position => &["P.X", "P.Y", "P.Z"],
            Aov::CameraNormal => &["Nc.X", "Nc.Y", "Nc.Z"],
            Aov::PrimitiveId => &["id"],
            Aov::Uv => &["u", "v"],
            Aov::ShadingNormal => &["Ns.X", "Ns.Y", "Ns.Z"],
            Aov::Uncertain => &["uncertain"],
        }
    }
}
