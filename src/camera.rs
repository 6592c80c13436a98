//! A pinhole camera at one instant: eye, target, up, vertical field of view and clip planes, with
//! the transforms the GPU passes and the popping test share (so both agree on pixel positions).

use glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

/// Near and far clip distances in metres of a camera that states none (keyframed cameras; a glTF
/// camera has its own `znear`, and its `zfar` when it has one). The far plane is generous: pool
/// scenes are tens of metres.
pub const NEAR_M: f32 = 0.05;
pub const FAR_M: f32 = 1000.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub fov_y_deg: f32,
    /// Clip planes, as view depths in metres (0 < near < far).
    pub near_m: f32,
    pub far_m: f32,
}

/// A view closer to vertical than this angle (radians) has no roll defined by +y up: it takes
/// [`up_for_view`]'s fallback instead.
pub const VERTICAL_VIEW_RAD: f32 = 1e-3;

/// The up vector a camera looking along `view` uses: +y, unless the view is within
/// [`VERTICAL_VIEW_RAD`] of straight down or up. Then the picture keeps the orientation of a
/// camera that faces +z and tilts down (or up) to the vertical: its top points along +z when
/// looking down and along -z when looking up. (No rule can be continuous for every path through
/// the vertical; this one is for the common tilt.)
pub fn up_for_view(view: Vec3) -> Vec3 {
    let horizontal = (view.x * view.x + view.z * view.z).sqrt();
    if horizontal > VERTICAL_VIEW_RAD.sin() * view.length() {
        Vec3::Y
    } else if view.y < 0.0 {
        Vec3::Z
    } else {
        Vec3::NEG_Z
    }
}

/// World points to pixel coordinates for one camera and image size ([`Camera::pixels`]).
#[derive(Clone, Copy, Debug)]
pub struct Pixels {
    clip_from_world: Mat4,
    size: Vec2,
}

impl Pixels {
    /// [`Camera::pixel_of`].
    pub fn pixel_of(&self, point_in_world: Vec3) -> Option<Vec2> {
        let clip = self.clip_from_world * point_in_world.extend(1.0);
        if clip.w <= 1e-6 {
            return None;
        }
        let ndc = clip.xy() / clip.w;
        Some(Vec2::new(
            (ndc.x * 0.5 + 0.5) * self.size.x,
            (0.5 - ndc.y * 0.5) * self.size.y,
        ))
    }
}

impl Camera {
    /// Unit view direction, from the eye toward the target: depths are measured along it. A
    /// target on the eye looks along +z, as [`Camera::view_from_world`] does.
    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye).try_normalize().unwrap_or(Vec3::Z)
    }

    /// Depth along the view axis of a world point (negative behind the eye): what the EXR's `Z`
    /// holds, as Blender writes it.
    pub fn view_depth(&self, point_in_world: Vec3) -> f32 {
        (point_in_world - self.eye).dot(self.forward())
    }

    /// A camera at `eye` looking at `target`, with [`up_for_view`]'s up vector and the default
    /// clip planes [`NEAR_M`] and [`FAR_M`].
    pub fn looking_at(eye: Vec3, target: Vec3, fov_y_deg: f32) -> Camera {
        Camera {
            eye,
            target,
            up: up_for_view(target - eye),
            fov_y_deg,
            near_m: NEAR_M,
            far_m: FAR_M,
        }
    }

    /// World to camera space. Never NaN for finite inputs: a target on the eye looks along +z, and
    /// an up vector along the view is replaced by [`up_for_view`]'s.
    pub fn view_from_world(&self) -> Mat4 {
        let (mut view, mut target) = (self.target - self.eye, self.target);
        if view.length().is_nan() || view.length() <= 1e-6 {
            view = Vec3::Z;
            target = self.eye + view;
        }
        let up = if view.normalize().cross(self.up.normalize_or_zero()).length()
            > VERTICAL_VIEW_RAD.sin() * 0.5
        {
            self.up
        } else {
            up_for_view(view)
        };
        glam::camera::rh::view::look_at_mat4(self.eye, target, up)
    }

    /// Right-handed perspective with depth in [0, 1] and y up in NDC: wgpu's clip space, which is
    /// glam's "directx" convention.
    pub fn clip_from_view(&self, aspect: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective(
            self.fov_y_deg.to_radians(),
            aspect,
            self.near_m,
            self.far_m,
        )
    }

    pub fn clip_from_world(&self, width: u32, height: u32) -> Mat4 {
        self.clip_from_view(width as f32 / height as f32) * self.view_from_world()
    }

    /// Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point, or `None`
    /// when it is behind the eye.
    pub fn pixel_of(&self, point_in_world: Vec3, width: u32, height: u32) -> Option<Vec2> {
        self.pixels(width, height).pixel_of(point_in_world)
    }

    /// [`Self::pixel_of`] for many points of one image: the projection built once.
    pub fn pixels(&self, width: u32, height: u32) -> Pixels {
        Pixels {
            clip_from_world: self.clip_from_world(width, height),
            size: Vec2::new(width as f32, height as f32),
        }
    }

    /// Unit direction of the sight ray through pixel coordinates `pixel` (same convention as `pixel_of`).
    pub fn ray_through_pixel(&self, pixel: Vec2, width: u32, height: u32) -> Vec3 {
        self.pixel_rays(width, height).direction(pixel)
    }

    /// [`Self::ray_through_pixel`] for many pixels of one image: the inverse projection once.
    pub fn pixel_rays(&self, width: u32, height: u32) -> PixelRays {
        PixelRays {
            world_from_clip: self.clip_from_world(width, height).inverse(),
            eye: self.eye,
            size: Vec2::new(width as f32, height as f32),
        }
    }
}

/// Sight rays through the pixels of one image (see [`Camera::pixel_rays`]).
#[derive(Clone, Copy, Debug)]
pub struct PixelRays {
    world_from_clip: Mat4,
    eye: Vec3,
    size: Vec2,
}

impl PixelRays {
    /// Unit direction of the sight ray through pixel coordinates `pixel` (x right, y down, pixel
    /// centres at +0.5).
    pub fn direction(&self, pixel: Vec2) -> Vec3 {
        let ndc = Vec2::new(
            pixel.x / self.size.x * 2.0 - 1.0,
            1.0 - pixel.y / self.size.y * 2.0,
        );
        let far = self.world_from_clip * ndc.extend(1.0).extend(1.0);
        (far.xyz() / far.w - self.eye).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertical_and_degenerate_views_give_finite_matrices_with_the_stated_up() {
        for (eye, target) in [
            (Vec3::new(0.0, 3.0, 0.0), Vec3::new(0.0, -1.0, 0.0)),
            (Vec3::new(0.0, 3.0, 0.0), Vec3::new(0.0, 9.0, 0.0)),
            (Vec3::new(1.0, 3.0, 2.0), Vec3::new(1.0, 3.0, 2.0)),
            (Vec3::new(0.0, 3.0, 0.0), Vec3::new(1e-5, -1.0, 0.0)),
        ] {
            let camera = Camera::looking_at(eye, target, 50.0);
            let matrix = camera.clip_from_world(64, 36);
            assert!(matrix.is_finite(), "{eye} -> {target}: {matrix}");
            // Even with +y forced as up, the matrix is finite.
            let forced = Camera {
                up: Vec3::Y,
                ..camera
            };
            assert!(forced.clip_from_world(64, 36).is_finite());
        }
        // Looking down, the picture's top points along +z: a point at +z is above the centre.
        let down = Camera::looking_at(Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO, 50.0);
        assert_eq!(down.up, Vec3::Z);
        let ahead = down.pixel_of(Vec3::new(0.0, 0.0, 0.5), 64, 36).unwrap();
        assert!(ahead.y < 18.0, "{ahead}");
        // Which is the limit of a camera facing +z tilting down: the same picture a hair off
        // the vertical with +y up.
        let tilted = Camera::looking_at(Vec3::new(0.0, 3.0, 0.0), Vec3::new(0.0, 0.0, 0.01), 50.0);
        assert_eq!(tilted.up, Vec3::Y);
        let ahead_tilted = tilted.pixel_of(Vec3::new(0.0, 0.0, 0.5), 64, 36).unwrap();
        assert!(
            (ahead - ahead_tilted).length() < 0.5,
            "{ahead} vs {ahead_tilted}"
        );
        let up = Camera::looking_at(Vec3::ZERO, Vec3::Y, 50.0);
        assert_eq!(up.up, Vec3::NEG_Z);
        // An ordinary view keeps +y and exactly glam's matrix.
        let usual = Camera::looking_at(Vec3::new(1.0, 3.0, 8.0), Vec3::ZERO, 50.0);
        assert_eq!(usual.up, Vec3::Y);
        assert_eq!(
            usual.view_from_world(),
            glam::camera::rh::view::look_at_mat4(usual.eye, usual.target, Vec3::Y)
        );
    }

    #[test]
    fn pixel_and_ray_are_inverse() {
        let cam = Camera {
            eye: Vec3::new(1.0, 3.0, 8.0),
            target: Vec3::new(0.0, -1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 50.0,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let p = Vec3::new(0.7, -0.5, 1.2);
        let px = cam.pixel_of(p, 640, 360).unwrap();
        let dir = cam.ray_through_pixel(px, 640, 360);
        let expected = (p - cam.eye).normalize();
        assert!((dir - expected).length() < 1e-4, "{dir} vs {expected}");
        let centre = cam.pixel_of(cam.target, 640, 360).unwrap();
        assert!((centre - Vec2::new(320.0, 180.0)).length() < 1e-3);
    }
}
