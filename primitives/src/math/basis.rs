//! Orthonormal bases from a single unit vector.

use glam::DVec3;

/// Two unit vectors `(e1, e2)` such that `(e1, e2, n)` is a right-handed orthonormal basis
/// (`e1 × e2 = n`), continuous except across `n.z = 0` with `n.x = 0`; branch-free method of
/// Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017).
///
/// `n` must be unit length.
#[must_use]
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0_f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let e1 = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let e2 = DVec3::new(b, sign + n.y * n.y * a, -n.y);
    (e1, e2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal_and_right_handed() {
        for n in [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(1.0, 2.0, -3.0).normalize(),
            DVec3::new(-1e-9, 1.0, -1e-12).normalize(),
        ] {
            let (e1, e2) = orthonormal_basis(n);
            assert!((e1.length() - 1.0).abs() < 1e-14);
            assert!((e2.length() - 1.0).abs() < 1e-14);
            assert!(e1.dot(e2).abs() < 1e-14);
            assert!(e1.dot(n).abs() < 1e-14 && e2.dot(n).abs() < 1e-14);
            assert!((e1.cross(e2) - n).length() < 1e-14, "not right-handed for {n}");
        }
    }
}
