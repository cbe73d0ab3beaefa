//! Lens distortion in normalised image coordinates (`x = X / Z`,
//! `y = Y / Z`): the radial-tangential polynomial of OpenCV, COLMAP's
//! `SIMPLE_RADIAL`, `RADIAL` and `OPENCV` models and nerfstudio's `OPENCV`
//! camera (which adds `k3`, `k4` as the `r^6`, `r^8` terms).
//!
//! ```text
//! r2 = x^2 + y^2
//! d  = 1 + k1 r2 + k2 r2^2 + k3 r2^3 + k4 r2^4
//! xd = x d + 2 p1 x y + p2 (r2 + 2 x^2)
//! yd = y d + p1 (r2 + 2 y^2) + 2 p2 x y
//! ```
//!
//! Pixels are distorted points; a ray is found by inverting the map
//! ([`Distortion::undistort`], Newton's method with the exact Jacobian).

/// Radial (`k1..k4`) and tangential (`p1`, `p2`) distortion coefficients;
/// all zero is a pinhole camera.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Distortion {
    /// Radial coefficient of `r^2`.
    pub k1: f64,
    /// Radial coefficient of `r^4`.
    pub k2: f64,
    /// Radial coefficient of `r^6`.
    pub k3: f64,
    /// Radial coefficient of `r^8`.
    pub k4: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
}

/// Newton iterations of [`Distortion::undistort`] at most.
const MAX_ITERATIONS: usize = 50;

impl Distortion {
    /// No distortion.
    pub const NONE: Self = Self {
        k1: 0.0,
        k2: 0.0,
        k3: 0.0,
        k4: 0.0,
        p1: 0.0,
        p2: 0.0,
    };

    /// True when every coefficient is zero (a pinhole camera).
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// True when every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        [self.k1, self.k2, self.k3, self.k4, self.p1, self.p2]
            .iter()
            .all(|v| v.is_finite())
    }

    /// The distorted point of the undistorted normalised point `(x, y)`.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        if self.is_none() {
            return (x, y);
        }
        let r2 = x * x + y * y;
        let d = self.radial(r2);
        (
            x * d + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * d + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// The undistorted normalised point whose distortion is `(xd, yd)`:
    /// Newton's method from `(xd, yd)`, stopping when the residual is below
    /// `1e-14` (or after 50 iterations, returning the best estimate; that
    /// happens only far outside the image, where the polynomial folds over).
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        if self.is_none() {
            return (xd, yd);
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..MAX_ITERATIONS {
            let (fx, fy) = self.distort(x, y);
            let (rx, ry) = (fx - xd, fy - yd);
            if rx.abs().max(ry.abs()) < 1e-14 {
                break;
            }
            let [[a, b], [c, d]] = self.jacobian(x, y);
            let det = a * d - b * c;
            if det.abs() < 1e-300 || !det.is_finite() {
                break;
            }
            x -= (d * rx - b * ry) / det;
            y -= (a * ry - c * rx) / det;
        }
        (x, y)
    }

    /// `1 + k1 r2 + k2 r2^2 + k3 r2^3 + k4 r2^4`.
    fn radial(&self, r2: f64) -> f64 {
        1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * (self.k3 + r2 * self.k4)))
    }

    /// `d radial / d r2`.
    fn radial_slope(&self, r2: f64) -> f64 {
        self.k1 + r2 * (2.0 * self.k2 + r2 * (3.0 * self.k3 + r2 * 4.0 * self.k4))
    }

    /// `[[dxd/dx, dxd/dy], [dyd/dx, dyd/dy]]` at `(x, y)`.
    fn jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let r2 = x * x + y * y;
        let d = self.radial(r2);
        let s = self.radial_slope(r2);
        let (p1, p2) = (self.p1, self.p2);
        [
            [
                d + 2.0 * x * x * s + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * x * y * s + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * x * y * s + 2.0 * p1 * x + 2.0 * p2 * y,
                d + 2.0 * y * y * s + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens() -> Distortion {
        Distortion {
            k1: -0.28,
            k2: 0.09,
            k3: -0.01,
            k4: 0.002,
            p1: 1e-3,
            p2: -2e-3,
        }
    }

    /// The analytic Jacobian against central differences.
    #[test]
    fn jacobian_matches_finite_differences() {
        let l = lens();
        let h = 1e-6;
        for &(x, y) in &[(0.1, -0.2), (-0.5, 0.3), (0.7, 0.45)] {
            let j = l.jacobian(x, y);
            let (a, c) = {
                let (p, q) = (l.distort(x + h, y), l.distort(x - h, y));
                ((p.0 - q.0) / (2.0 * h), (p.1 - q.1) / (2.0 * h))
            };
            let (b, d) = {
                let (p, q) = (l.distort(x, y + h), l.distort(x, y - h));
                ((p.0 - q.0) / (2.0 * h), (p.1 - q.1) / (2.0 * h))
            };
            for (got, want) in [(j[0][0], a), (j[0][1], b), (j[1][0], c), (j[1][1], d)] {
                assert!((got - want).abs() < 1e-7, "{got} vs {want} at ({x}, {y})");
            }
        }
    }

    /// A pinhole camera's maps are the identity, bit for bit.
    #[test]
    fn no_distortion_is_the_identity() {
        let d = Distortion::default();
        assert!(d.is_none());
        assert_eq!(d.distort(0.3, -0.7), (0.3, -0.7));
        assert_eq!(d.undistort(0.3, -0.7), (0.3, -0.7));
    }
}
