//! Simple height fields: a flat plane (the oracle case of ALGORITHM §6) and one built from
//! closures, for tests that need a surface of a given shape.

use super::HeightField;

/// A horizontal plane at `level_m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlatHeightField {
    pub level_m: f64,
}

impl HeightField for FlatHeightField {
    fn height(&self, _x: f64, _z: f64) -> f64 {
        self.level_m
    }

    fn gradient(&self, _x: f64, _z: f64) -> (f64, f64) {
        (0.0, 0.0)
    }

    fn hessian(&self, _x: f64, _z: f64) -> (f64, f64, f64) {
        (0.0, 0.0, 0.0)
    }
}

type HeightFn = dyn Fn(f64, f64) -> f64 + Send + Sync;
type GradientFn = dyn Fn(f64, f64) -> (f64, f64) + Send + Sync;

/// A height field from a closure `h(x, z)`; the gradient is the given closure or, without one,
/// central differences (accurate to ~1e-9 for smooth surfaces of metre scale).
pub struct FnHeightField {
    height: Box<HeightFn>,
    gradient: Option<Box<GradientFn>>,
}

impl FnHeightField {
    pub fn new(height: impl Fn(f64, f64) -> f64 + Send + Sync + 'static) -> Self {
        Self {
            height: Box::new(height),
            gradient: None,
        }
    }

    /// Uses `gradient` (dh/dx, dh/dz) instead of finite differences.
    pub fn with_gradient(
        mut self,
        gradient: impl Fn(f64, f64) -> (f64, f64) + Send + Sync + 'static,
    ) -> Self {
        self.gradient = Some(Box::new(gradient));
        self
    }
}

impl std::fmt::Debug for FnHeightField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FnHeightField")
            .field("analytic_gradient", &self.gradient.is_some())
            .finish()
    }
}

impl HeightField for FnHeightField {
    fn height(&self, x: f64, z: f64) -> f64 {
        (self.height)(x, z)
    }

    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        if let Some(gradient) = &self.gradient {
            return gradient(x, z);
        }
        // Step relative to the coordinate so far-off points do not lose the difference to round-off.
        let step_x = 1e-5 * x.abs().max(1.0);
        let step_z = 1e-5 * z.abs().max(1.0);
        let h = &self.height;
        (
            (h(x + step_x, z) - h(x - step_x, z)) / (2.0 * step_x),
            (h(x, z + step_z) - h(x, z - step_z)) / (2.0 * step_z),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_field_is_level_with_an_up_normal() {
        let flat = FlatHeightField { level_m: -1.5 };
        assert_eq!(flat.height(3.0, -7.0), -1.5);
        assert_eq!(flat.normal(3.0, -7.0), glam::DVec3::Y);
    }

    #[test]
    fn closure_field_differentiates_numerically_or_uses_the_given_gradient() {
        let bowl = FnHeightField::new(|x, z| 0.1 * x * x - 0.3 * z * z + 0.2 * x * z);
        let (gx, gz) = bowl.gradient(2.0, -1.0);
        assert!((gx - (0.4 - 0.2)).abs() < 1e-8, "{gx}");
        assert!((gz - (0.6 + 0.4)).abs() < 1e-8, "{gz}");
        let tilted = FnHeightField::new(|x, _| 0.5 * x).with_gradient(|_, _| (0.5, 0.0));
        assert_eq!(tilted.gradient(1.0, 1.0), (0.5, 0.0));
        let expected = glam::DVec3::new(-0.5, 1.0, 0.0).normalize();
        assert!((tilted.normal(0.0, 0.0) - expected).length() < 1e-15);
    }
}
