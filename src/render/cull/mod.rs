//! Culling before tracing: which pixels can see anything ([`footprint`]: a box's image
//! rectangle under a camera, and the [`footprint::Coverage`] of a scene), and which pieces each
//! pixel can see (`piece_bins`). Both only ever leave out rays or pieces that cannot be hit, so
//! a culled render is bit for bit the render without culling.

pub mod footprint;
pub(crate) mod piece_bins;

use crate::camera::Camera;
use crate::scene::Scene;
use footprint::Coverage;

impl Scene {
    /// The pixels of `camera` whose rays can meet an object: [`Camera::coverage`] of
    /// [`Scene::bounds_parts`], allowing for [`Scene::origin_rounding`] at the eye; `None` where
    /// the camera cannot say. A render skips the others.
    #[must_use]
    pub fn coverage(&self, camera: &Camera) -> Option<Coverage> {
        camera.coverage(&self.bounds_parts(), self.origin_rounding(camera.eye))
    }
}
