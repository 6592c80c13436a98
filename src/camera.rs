//! A pinhole camera at one instant: eye, target, up and vertical field of view, with the
//! transforms the GPU passes and the popping test share (so both agree on pixel positions).

use glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

/// Near and far clip distances in metres. The far plane is generous: pool scenes are tens of metres.
pub const NEAR_M: f32 = 0.05;
pub const FAR_M: f32 = 1000.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub fov_y_deg: f32,
}

impl Camera {
    /// Unit view direction, from the eye toward the target: depths are measured along it.
    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye).normalize()
    }

    /// Depth along the view axis of a world point (negative behind the eye): what the EXR's `Z`
    /// holds, as Blender writes it.
    pub fn view_depth(&self, point_in_world: Vec3) -> f32 {
        (point_in_world - self.eye).dot(self.forward())
    }

    pub fn view_from_world(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye, self.target, self.up)
    }

    /// Right-handed perspective with depth in [0, 1] and y up in NDC: wgpu's clip space, which is
    /// glam's "directx" convention.
    pub fn clip_from_view(&self, aspect: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective(
            self.fov_y_deg.to_radians(),
            aspect,
            NEAR_M,
            FAR_M,
        )
    }

    pub fn clip_from_world(&self, width: u32, height: u32) -> Mat4 {
        self.clip_from_view(width as f32 / height as f32) * self.view_from_world()
    }

    /// Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point, or `None`
    /// when it is behind the eye.
    pub fn pixel_of(&self, point_in_world: Vec3, width: u32, height: u32) -> Option<Vec2> {
        let clip = self.clip_from_world(width, height) * point_in_world.extend(1.0);
        if clip.w <= 1e-6 {
            return None;
        }
        let ndc = clip.xy() / clip.w;
        Some(Vec2::new(
            (ndc.x * 0.5 + 0.5) * width as f32,
            (0.5 - ndc.y * 0.5) * height as f32,
        ))
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
    fn pixel_and_ray_are_inverse() {
        let cam = Camera {
            eye: Vec3::new(1.0, 3.0, 8.0),
            target: Vec3::new(0.0, -1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 50.0,
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
