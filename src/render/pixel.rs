//! The one place hits become AOV values: a pixel's hit (or miss) written as every requested
//! AOV's channels, with or without a hit record.

use super::shade::{headlight, shade};
use super::{channel_offset_in, NoRayCounts};
use crate::aov::Aov;
use crate::camera::Camera;
use crate::render::cull::footprint::Coverage;
use crate::render::cull::piece_bins::PieceBins;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use zeroset_primitives::root::thread_uncertain_events;
use zeroset_primitives::{HitRequest, RawHit, Ray, SurfaceHit};

/// Completes the closest hit (if any) of a pixel's `ray` and writes every AOV of `context`.
#[inline(always)]
pub(super) fn write_pixel(
    pixel: &mut [f32],
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    hit: Option<(u32, RawHit)>,
) {
    write_pixel_knowing(pixel, scene, context, ray, hit, None);
}

/// [`write_pixel`], given the hit's `normal_at_f32` where the trace found it (`known_normal`:
/// the record-free path takes it instead of asking the primitive again).
#[inline(always)]
pub(super) fn write_pixel_knowing(
    pixel: &mut [f32],
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    hit: Option<(u32, RawHit)>,
    known_normal: Option<Vec3>,
) {
    // (no closure for these three: left to the compiler, one was not inlined)
    match context.record_free {
        RecordFree::Scalars => return write_without_record::<false, false>(pixel, scene, context, ray, hit, None),
        RecordFree::WithNormal => {
            return write_without_record::<true, false>(pixel, scene, context, ray, hit, known_normal)
        }
        RecordFree::WithHeadlight => {
            return write_without_record::<true, true>(pixel, scene, context, ray, hit, known_normal)
        }
        RecordFree::No => {}
    }
    #[allow(clippy::manual_map, reason = "no closure: see `completed`")]
    let hit = match hit {
        Some((object, raw)) => Some(completed(scene, context, ray, object, &raw)),
        None => None,
    };
    let mut rest = &mut pixel[..];
    for aov in context.aovs {
        let n = write_aov(rest, scene, *aov, ray, hit.as_ref(), context);
        rest = &mut rest[n..];
    }
}

/// [`write_pixel`] where every AOV is one that [`RecordFree`] allows: the values
/// [`write_aov`] writes (the depth from the point `ray.at(t)` and the normal `normal_at`, as
/// [`SurfaceHit::complete`] makes them; the headlight's colour as [`shade`] makes it), without
/// building the hit record. `NORMAL`: the AOVs include the normal or the beauty (`normal_at` is
/// asked); `HEADLIGHT`: the beauty.
#[inline(always)]
pub(super) fn write_without_record<const NORMAL: bool, const HEADLIGHT: bool>(
    pixel: &mut [f32],
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    hit: Option<(u32, RawHit)>,
    known_normal: Option<Vec3>,
) {
    let Some((object, raw)) = hit else {
        write_miss(pixel, context);
        return;
    };
    // the f32 normal the AOV stores (`normal_at` rounded: the same values as the record's),
    // unless the trace found it already
    let normal = if NORMAL {
        known_normal.unwrap_or_else(|| scene.objects[object as usize].primitive.normal_at_f32(ray, &raw))
    } else {
        Vec3::ZERO
    };
    let at = &context.value_offsets;
    if let Some(k) = at.depth {
        pixel[k] = context.camera.depth(ray.at(raw.t), raw.t) as f32;
    }
    if let Some(k) = at.distance {
        pixel[k] = raw.t as f32;
    }
    if let Some(k) = at.alpha {
        pixel[k] = 1.0;
    }
    if let Some(k) = at.id {
        pixel[k] = object as f32;
    }
    if let (true, Some(k)) = (NORMAL, at.normal) {
        pixel[k..k + 3].copy_from_slice(&normal.to_array());
    }
    if let (true, Some(k)) = (HEADLIGHT, at.beauty) {
        let colour = scene.objects[object as usize].material.color;
        pixel[k..k + 3].copy_from_slice(&headlight(colour, scene.ambient, normal, ray.dir).to_array());
    }
}

/// The hit record of `object`'s `raw` hit along a pixel's `ray`, completed as `context` asks,
/// and its shading normal where the beauty is shaded. Always inlined, never a closure: left to
/// the compiler, the record came back through memory (a copy of it for every pixel hit).
#[inline(always)]
pub(super) fn completed(
    scene: &Scene,
    context: &RowContext,
    ray: &Ray,
    object: u32,
    raw: &RawHit,
) -> (u32, SurfaceHit, Option<DVec3>) {
    let primitive = &*scene.objects[object as usize].primitive;
    let hit = SurfaceHit::complete(primitive, ray, raw, context.request);
    let shading_normal = if context.shading {
        primitive.shading_normal_at(ray, raw).or(hit.normal)
    } else {
        None
    };
    (object, hit, shading_normal)
}

/// Writes the miss values of every AOV of `context` into `pixel`.
#[inline(always)]
pub(super) fn write_miss(pixel: &mut [f32], context: &RowContext) {
    pixel.copy_from_slice(&context.miss_pixel);
}

/// The values every AOV of `context` takes where nothing is hit (the same for every pixel).
pub(super) fn miss_pixel(scene: &Scene, context: &RowContext) -> Vec<f32> {
    let camera = context.camera;
    let mut pixel = vec![0.0; context.channels];
    let mut rest = &mut pixel[..];
    for aov in context.aovs {
        let n = write_aov(rest, scene, *aov, &Ray::new(camera.eye, camera.forward), None, context);
        rest = &mut rest[n..];
    }
    pixel
}

/// Whether a render's pixels are written without a hit record ([`write_without_record`]), and
/// which of its values they need: only where every AOV is a value of the hit's `t` and object
/// (Depth, Distance, Alpha, PrimitiveId), its normal (Normal) or the headlight's colour (the
/// beauty of a scene without lights). The record, its copies and the match over its AOVs were
/// about 45 instructions of a hit pixel's 555 in the quadrics scene's Depth render
/// (cachegrind). Medians of 11–15 alternating runs: Depth renders quadrics 0.0144 → 0.0120 s,
/// spheres1k 0.0186 → 0.0165 s; AOV renders (Depth, Normal, Alpha) quadrics 0.0219 → 0.0195 s,
/// spheres1k 0.0302 → 0.0281 s, mesh4 0.0319 → 0.0306 s, mesh6 0.0336 → 0.0329 s; default
/// renders quadrics 0.0265 → 0.0249 s, mesh4 and mesh6 unchanged. (One writer for Position
/// too, with the point made up front, was 3–8 % slower everywhere, Depth renders included.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RecordFree {
    /// Some AOV needs the record: [`write_pixel`]'s general path.
    No,
    /// Depth, Distance, Alpha, PrimitiveId.
    Scalars,
    /// Those and Normal.
    WithNormal,
    /// Those, Normal and the headlight's beauty.
    WithHeadlight,
}

impl RecordFree {
    /// Whether the record-free pixel writes the hit's normal (or shades with it).
    #[inline(always)]
    pub(super) fn writes_normal(self) -> bool {
        matches!(self, RecordFree::WithNormal | RecordFree::WithHeadlight)
    }

    /// The path of a render of `aovs` in `scene`.
    pub(super) fn of(aovs: &[Aov], scene: &Scene) -> Self {
        let scalar = |a: &Aov| matches!(a, Aov::Depth | Aov::Distance | Aov::Alpha | Aov::PrimitiveId);
        if aovs.iter().all(scalar) {
            Self::Scalars
        } else if aovs.iter().all(|a| scalar(a) || *a == Aov::Normal) {
            Self::WithNormal
        } else if scene.lights.is_empty() && aovs.iter().all(|a| scalar(a) || matches!(a, Aov::Normal | Aov::Beauty)) {
            Self::WithHeadlight
        } else {
            Self::No
        }
    }
}

/// Where each value a record-free pixel writes ([`write_without_record`]) sits in the pixel:
/// the offset of its first channel, for the AOVs rendered. Worked out once per render, so that a
/// pixel stores each value at its place instead of walking the AOV list (the walk's match and
/// slicing were a third of the row loop's own time in the level-4 mesh's default render).
#[derive(Clone, Copy, Debug)]
pub(super) struct ValueOffsets {
    pub(super) depth: Option<usize>,
    pub(super) distance: Option<usize>,
    pub(super) alpha: Option<usize>,
    pub(super) id: Option<usize>,
    pub(super) normal: Option<usize>,
    pub(super) beauty: Option<usize>,
}

impl ValueOffsets {
    /// The offsets of `aovs` (in channel order, without repeats).
    pub(super) fn of(aovs: &[Aov]) -> Self {
        let at = |aov| channel_offset_in(aovs, aov);
        Self {
            depth: at(Aov::Depth),
            distance: at(Aov::Distance),
            alpha: at(Aov::Alpha),
            id: at(Aov::PrimitiveId),
            normal: at(Aov::Normal),
            beauty: at(Aov::Beauty),
        }
    }
}

/// What every row of one render shares.
pub(super) struct RowContext<'a> {
    pub(super) aovs: &'a [Aov],
    pub(super) request: HitRequest,
    pub(super) shading: bool,
    pub(super) beauty: bool,
    pub(super) channels: usize,
    pub(super) world_to_camera: glam::DMat4,
    pub(super) depth_miss: f32,
    pub(super) camera: &'a Camera,
    pub(super) no_ray: NoRayCounts,
    /// Beauty of the uncovered part of a pixel: the background, or black (premultiplied).
    pub(super) miss_colour: DVec3,
    /// Every AOV's values where nothing is hit ([`miss_pixel`]).
    pub(super) miss_pixel: Vec<f32>,
    /// Which AOVs' pixels are written without a hit record ([`write_without_record`]).
    pub(super) record_free: RecordFree,
    /// Where those pixels' values go.
    pub(super) value_offsets: ValueOffsets,
    /// Where the `Uncertain` channel is in a pixel, if it was asked for.
    pub(super) uncertain_offset: Option<usize>,
    /// The pixel centres whose rays can meet an object ([`Scene::coverage`]), if the camera
    /// can say; the others see nothing and are not traced.
    pub(super) seen: Option<Coverage>,
    /// The pieces each pixel can see ([`PieceBins`]: a lone mesh's leaves, or the objects of a
    /// scene of several), where a pinhole sees the scene: its pixels are traced against those
    /// alone, instead of in packets.
    pub(super) bins: Option<PieceBins<'a>>,
}

/// Sets the pixel's `Uncertain` channel (if rendered) to 1 if this thread's root finder ran out of
/// budget since `exhausted_before` — that is, while this pixel's rays were traced — else 0.
#[inline(always)]
pub(super) fn flag_uncertain(pixel: &mut [f32], context: &RowContext, exhausted_before: u64) {
    if let Some(at) = context.uncertain_offset {
        pixel[at] = if thread_uncertain_events() == exhausted_before {
            0.0
        } else {
            1.0
        };
    }
}

/// Writes one AOV's channels for one pixel at the start of `out`; returns how many it wrote.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn write_aov(
    out: &mut [f32],
    scene: &Scene,
    aov: Aov,
    ray: &Ray,
    hit: Option<&(u32, SurfaceHit, Option<DVec3>)>,
    context: &RowContext,
) -> usize {
    let (world_to_camera, depth_miss, miss_colour) =
        (&context.world_to_camera, context.depth_miss, context.miss_colour);
    let mut put3 = |v: DVec3| {
        out[0] = v.x as f32;
        out[1] = v.y as f32;
        out[2] = v.z as f32;
        3
    };
    let Some((object, hit, shading_normal)) = hit else {
        return match aov {
            Aov::Beauty => put3(miss_colour),
            Aov::Normal | Aov::Position | Aov::CameraNormal | Aov::ShadingNormal => put3(DVec3::ZERO),
            Aov::Depth | Aov::Distance => {
                out[0] = depth_miss;
                1
            }
            Aov::PrimitiveId => {
                out[0] = -1.0;
                1
            }
            Aov::Alpha | Aov::Uncertain => {
                out[0] = 0.0;
                1
            }
            Aov::Uv => {
                out[..2].fill(0.0);
                2
            }
        };
    };
    let normal = hit.normal.unwrap_or(DVec3::ZERO);
    let scalar = match aov {
        Aov::Beauty => return put3(shade(scene, *object, ray, hit)),
        Aov::Normal => return put3(normal),
        Aov::Position => return put3(hit.point),
        Aov::CameraNormal => return put3(world_to_camera.transform_vector3(normal)),
        Aov::ShadingNormal => return put3(shading_normal.unwrap_or(normal)),
        Aov::Uv => {
            let uv = hit.uv.unwrap_or_default();
            out[0] = uv.x as f32;
            out[1] = uv.y as f32;
            return 2;
        }
        Aov::Alpha => 1.0,
        Aov::Depth => context.camera.depth(hit.point, hit.t) as f32,
        Aov::Distance => hit.t as f32,
        Aov::PrimitiveId => *object as f32,
        // set once the whole pixel is traced (`flag_uncertain`)
        Aov::Uncertain => 0.0,
    };
    out[0] = scalar;
    1
}
