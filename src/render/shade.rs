//! Shading: ambient, Lambert and Blinn-Phong per light with hard shadows, or a headlight at
//! the eye when the scene has no lights.

use crate::scene::{Light, Scene};
use crate::trace::scalar;
use glam::{DVec3, Vec3};
use zeroset_primitives::{facing, Interval, Ray, SurfaceHit};

/// Where a secondary (shadow) ray starts: the hit point moved along the facing normal by the
/// kernel's bound on its rounding error, `SurfaceHit::error` (primitive- and transform-aware, see
/// `zeroset_primitives::offset`), and rounded one ulp further away.
#[must_use]
pub fn secondary_offset(hit: &SurfaceHit, dir: DVec3) -> DVec3 {
    hit.secondary_origin(dir)
}

/// Local shading: ambient + Lambert (+ Blinn-Phong) per light, hard shadows by shadow rays. With
/// no lights, a headlight at the eye (no shadows).
#[must_use]
pub fn shade(scene: &Scene, object: u32, ray: &Ray, hit: &SurfaceHit) -> DVec3 {
    shade_with(scene, object, ray, hit, |r, range| scene.occluded(r, range))
}

/// [`shade`] at frame time `time`: shadow rays see moving objects where they are at that time.
#[must_use]
pub fn shade_at(scene: &Scene, object: u32, ray: &Ray, hit: &SurfaceHit, time: f64) -> DVec3 {
    shade_with(scene, object, ray, hit, |r, range| scene.occluded_at(r, range, time))
}

/// The colour of a surface of colour `colour` lit by the headlight of a scene without lights:
/// `colour·(ambient + max(n·v, 0))`, `n` the normal facing the viewer (zero for none) and
/// `v = −dir/‖dir‖` the direction back along the ray, worked out in f32 for the f32 beauty from
/// the normal rounded to f32, whichever way it faces, as `|n·d| / ‖d‖`, or `|n·d|` where `d`
/// is a unit vector within f32 rounding (every camera model's rays); a zero normal gives the
/// ambient term alone. Every path of the render shades with it, with or without a hit record:
/// the same bits. Against the f64 formula of before, at most 9 ulps (1.8·10⁻⁷) on the shipped
/// scenes' beauty.
#[inline(always)]
pub(super) fn headlight(colour: DVec3, ambient: DVec3, normal: Vec3, dir: DVec3) -> Vec3 {
    let dir = dir.as_vec3();
    let length_squared = dir.length_squared();
    // a unit direction (every camera model's) within 2⁻²¹ spares the square root and division:
    // `|n·d|` is then within 2⁻²² of the cosine; `max` turns a NaN (a direction rounded to
    // zero or to infinity) into 0
    let dot = normal.dot(dir).abs();
    let cosine = if (length_squared - 1.0).abs() <= 1.0 / (1 << 21) as f32 {
        dot
    } else {
        (dot / length_squared.sqrt()).max(0.0)
    };
    colour.as_vec3() * (ambient.as_vec3() + Vec3::splat(cosine))
}

#[inline(always)]
pub(super) fn shade_with(
    scene: &Scene,
    object: u32,
    ray: &Ray,
    hit: &SurfaceHit,
    occluded: impl Fn(&Ray, Interval) -> bool,
) -> DVec3 {
    let material = &scene.objects[object as usize].material;
    // the direction and the normal read a component at a time: the hit record was just written
    // field by field, and a 16-byte load straddling two of those writes waits for both to reach
    // the cache (a store-forwarding stall on every pixel, 6 % of the quadrics' default render)
    let by_component = |v: &DVec3| DVec3::new(scalar(&v.x), scalar(&v.y), scalar(&v.z));
    let dir = by_component(&ray.dir);
    let n = hit
        .normal
        .as_ref()
        .map_or(DVec3::ZERO, |n| facing(by_component(n), dir));
    if scene.lights.is_empty() {
        return headlight(material.color, scene.ambient, n.as_vec3(), dir).as_dvec3();
    }
    let view = -dir.normalize();
    let origin = secondary_offset(hit, ray.dir);
    let mut colour = material.color * scene.ambient;
    for light in &scene.lights {
        let (to_light, distance, intensity) = match *light {
            Light::Point { position, intensity } => {
                let d = position - origin;
                let len = d.length();
                (d / len, len, intensity / (len * len))
            }
            Light::Directional { direction, intensity } => (-direction.normalize(), f64::INFINITY, intensity),
        };
        let cos = n.dot(to_light);
        if cos <= 0.0 || occluded(&Ray::new(origin, to_light), Interval::new(0.0, distance)) {
            continue;
        }
        colour += material.color * intensity * cos;
        if material.specular > 0.0 {
            let half = (to_light + view).normalize();
            colour += material.specular * intensity * n.dot(half).max(0.0).powf(material.shininess);
        }
    }
    colour
}
