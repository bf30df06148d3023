//! Analytic displacement fields.

use cgcontact::glam::DVec3;

/// A smooth indentation of a block's top face by a sphere, as an analytic field.
///
/// The top face (z = `top`) sinks by `depth` under `center` (x, y) with a Gaussian profile of width
/// `width`; the sinking decays linearly with depth below the top, reaching zero at z = `bottom`, and
/// material is pushed slightly outwards (a radial bulge of 30 % of the sink). Smooth, so every cell
/// stays valid (det J > 0) while `depth` is below about half a cell size per cell of width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Indentation {
    /// (x, y) of the indenter's axis; its z is ignored.
    pub center: DVec3,
    /// Width (standard deviation) of the Gaussian profile.
    pub width: f64,
    /// Largest downward displacement, at the top under the center.
    pub depth: f64,
    /// z of the top face.
    pub top: f64,
    /// z where the displacement vanishes.
    pub bottom: f64,
}

impl Indentation {
    /// Displacement at undeformed position `x`.
    #[must_use]
    pub fn displacement(&self, x: DVec3) -> DVec3 {
        let d = DVec3::new(x.x - self.center.x, x.y - self.center.y, 0.0);
        let profile = (-d.length_squared() / (2.0 * self.width * self.width)).exp();
        let decay = ((x.z - self.bottom) / (self.top - self.bottom)).clamp(0.0, 1.0);
        let sink = self.depth * profile * decay;
        DVec3::new(
            0.3 * sink * d.x / self.width,
            0.3 * sink * d.y / self.width,
            -sink,
        )
    }
}
