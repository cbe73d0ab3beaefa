//! Real spherical harmonics of a unit direction, the view encoding of the
//! fast field (as Instant-NGP and nerfacto encode the viewing direction):
//! the `degree^2` functions of bands `0..degree`, orthonormal over the
//! sphere (`∫ Y_i Y_j dω = δ_ij`).

use burn::tensor::Tensor;

/// The highest number of bands [`sh_encoding`] computes.
pub const MAX_SH_DEGREE: usize = 4;

/// Width of the encoding of `degree` bands (`degree` clamped to
/// `1..=MAX_SH_DEGREE`).
pub fn sh_dim(degree: usize) -> usize {
    let d = degree.clamp(1, MAX_SH_DEGREE);
    d * d
}

/// The real spherical harmonics of bands `0..degree` (clamped to
/// `1..=MAX_SH_DEGREE`) at unit directions, band by band, each band's
/// functions in the order `m = -l..=l`.
///
/// # Shapes
/// - `dirs`: `[n, 3]`, unit length; output: `[n, sh_dim(degree)]`.
pub fn sh_encoding(dirs: Tensor<2>, degree: usize) -> Tensor<2> {
    let degree = degree.clamp(1, MAX_SH_DEGREE);
    let [n, _] = dirs.dims();
    let x = dirs.clone().narrow(1, 0, 1);
    let y = dirs.clone().narrow(1, 1, 1);
    let z = dirs.narrow(1, 2, 1);
    let mut out = vec![x.zeros_like().add_scalar(0.282_094_791_773_878_14)];
    if degree > 1 {
        let c = 0.488_602_511_902_919_9;
        out.extend([
            y.clone().mul_scalar(c),
            z.clone().mul_scalar(c),
            x.clone().mul_scalar(c),
        ]);
    }
    let (xx, yy, zz) = (x.clone().square(), y.clone().square(), z.clone().square());
    if degree > 2 {
        let c = 1.092_548_430_592_079_2;
        out.extend([
            x.clone().mul(y.clone()).mul_scalar(c),
            y.clone().mul(z.clone()).mul_scalar(c),
            zz.clone()
                .mul_scalar(0.946_174_695_757_560_1)
                .sub_scalar(0.315_391_565_252_520_05),
            x.clone().mul(z.clone()).mul_scalar(c),
            xx.clone()
                .sub(yy.clone())
                .mul_scalar(0.546_274_215_296_039_6),
        ]);
    }
    if degree > 3 {
        let five_z2_minus_1 = zz.clone().mul_scalar(5.0).sub_scalar(1.0);
        out.extend([
            y.clone()
                .mul(xx.clone().mul_scalar(3.0).sub(yy.clone()))
                .mul_scalar(0.590_043_589_926_643_5),
            x.clone()
                .mul(y.clone())
                .mul(z.clone())
                .mul_scalar(2.890_611_442_640_554),
            y.clone()
                .mul(five_z2_minus_1.clone())
                .mul_scalar(0.457_045_799_464_465_8),
            z.clone()
                .mul(zz.mul_scalar(5.0).sub_scalar(3.0))
                .mul_scalar(0.373_176_332_590_115_4),
            x.clone()
                .mul(five_z2_minus_1)
                .mul_scalar(0.457_045_799_464_465_8),
            z.mul(xx.clone().sub(yy.clone()))
                .mul_scalar(1.445_305_721_320_277),
            x.mul(xx.sub(yy.mul_scalar(3.0)))
                .mul_scalar(0.590_043_589_926_643_5),
        ]);
    }
    let out = Tensor::cat(out, 1);
    debug_assert_eq!(out.dims(), [n, degree * degree]);
    out
}
