//! An orbit camera around a target point: yaw/pitch/distance, pan, zoom and reset, with
//! view and projection matrices for wgpu (right-handed, Y up, reversed-Z infinite
//! perspective: depth 1 at the near plane, 0 at infinity, compared with `Greater`).

use neural_cloth_core::geometry::{Mat4, Vec3};

/// Smallest allowed orbit distance in metres.
pub const MIN_DISTANCE_M: f32 = 0.05;
/// Largest allowed orbit distance in metres.
pub const MAX_DISTANCE_M: f32 = 1000.0;
/// Largest pitch magnitude in radians (just short of straight up or down).
pub const MAX_PITCH_RAD: f32 = std::f32::consts::FRAC_PI_2 - 0.01;

/// A camera orbiting `target` at `distance_m`, looking at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    /// Point looked at, world space, metres.
    pub target: Vec3,
    /// Rotation about world +Y in radians; 0 puts the camera on the +Z side of the target
    /// (looking at the front of a glTF character).
    pub yaw_rad: f32,
    /// Elevation in radians, positive looks down from above; clamped to ±[`MAX_PITCH_RAD`].
    pub pitch_rad: f32,
    /// Distance from the target in metres, in [`MIN_DISTANCE_M`, `MAX_DISTANCE_M`].
    pub distance_m: f32,
    /// Vertical field of view in radians, in (0, π); default 40°.
    pub fov_y_rad: f32,
    /// Near clip distance in metres, > 0; default 0.02.
    pub near_m: f32,
    /// The view that [`OrbitCamera::reset`] returns to.
    home: OrbitHome,
}

/// The stored "home" view of an [`OrbitCamera`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct OrbitHome {
    target: Vec3,
    yaw_rad: f32,
    pitch_rad: f32,
    distance_m: f32,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self::new(Vec3::new(0.0, 1.0, 0.0), 0.35, 0.15, 3.0)
    }
}

impl OrbitCamera {
    /// A camera looking at `target` from `distance_m` away; this view becomes the home view.
    pub fn new(target: Vec3, yaw_rad: f32, pitch_rad: f32, distance_m: f32) -> Self {
        let mut cam = Self {
            target,
            yaw_rad,
            pitch_rad,
            distance_m,
            fov_y_rad: 40f32.to_radians(),
            near_m: 0.02,
            home: OrbitHome {
                target,
                yaw_rad,
                pitch_rad,
                distance_m,
            },
        };
        cam.sanitize();
        cam.set_home();
        cam
    }

    /// A camera framing the axis-aligned box `[lo, hi]` (e.g. avatar plus garment) from the
    /// front, slightly from the side and above; the view becomes the home view.
    pub fn framing(lo: Vec3, hi: Vec3) -> Self {
        let mut cam = Self::default();
        cam.frame_bounds(lo, hi);
        cam.set_home();
        cam
    }

    /// Moves the target to the centre of `[lo, hi]` and backs off so the box fits the view.
    /// Non-finite or inverted bounds leave the camera unchanged.
    pub fn frame_bounds(&mut self, lo: Vec3, hi: Vec3) {
        let finite = lo.iter().chain(hi.iter()).all(|v| v.is_finite());
        if !finite || hi.x < lo.x || hi.y < lo.y || hi.z < lo.z {
            return;
        }
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo) * 0.5).norm().max(0.05);
        let half_fov = (self.fov_y_rad * 0.5).clamp(0.05, 1.5);
        self.target = centre;
        // The bounding sphere fits the vertical field of view exactly (wider views fit too).
        self.distance_m = radius / half_fov.sin();
        self.sanitize();
    }

    /// Makes the current view the one [`OrbitCamera::reset`] returns to.
    pub fn set_home(&mut self) {
        self.home = OrbitHome {
            target: self.target,
            yaw_rad: self.yaw_rad,
            pitch_rad: self.pitch_rad,
            distance_m: self.distance_m,
        };
    }

    /// Returns to the home view.
    pub fn reset(&mut self) {
        self.target = self.home.target;
        self.yaw_rad = self.home.yaw_rad;
        self.pitch_rad = self.home.pitch_rad;
        self.distance_m = self.home.distance_m;
    }

    /// Rotates around the target by `d_yaw_rad` and `d_pitch_rad`.
    pub fn orbit(&mut self, d_yaw_rad: f32, d_pitch_rad: f32) {
        if d_yaw_rad.is_finite() && d_pitch_rad.is_finite() {
            self.yaw_rad = (self.yaw_rad + d_yaw_rad).rem_euclid(std::f32::consts::TAU);
            self.pitch_rad += d_pitch_rad;
            self.sanitize();
        }
    }

    /// Moves the target in the view plane so that the scene follows a drag of
    /// `(dx_px, dy_px)` pixels in a viewport `viewport_height_px` pixels tall.
    pub fn pan(&mut self, dx_px: f32, dy_px: f32, viewport_height_px: f32) {
        if !(dx_px.is_finite() && dy_px.is_finite() && viewport_height_px > 0.0) {
            return;
        }
        let metres_per_px =
            2.0 * self.distance_m * (self.fov_y_rad * 0.5).tan() / viewport_height_px;
        let (right, up) = self.right_up();
        self.target += (-right * dx_px + up * dy_px) * metres_per_px;
    }

    /// Multiplies the distance by `factor` (< 1 zooms in), clamped to the allowed range.
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance_m *= factor;
            self.sanitize();
        }
    }

    /// Camera position in world space, metres.
    pub fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        self.target + Vec3::new(cp * sy, sp, cp * cy) * self.distance_m
    }

    /// Unit vectors pointing right and up on screen, in world space.
    pub fn right_up(&self) -> (Vec3, Vec3) {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        let right = Vec3::new(cy, 0.0, -sy);
        let back = Vec3::new(cp * sy, sp, cp * cy);
        (right, back.cross(&right))
    }

    /// `view_from_world`: right-handed look-at from [`OrbitCamera::eye`] to the target.
    pub fn view_from_world(&self) -> Mat4 {
        let (right, up) = self.right_up();
        let back = right.cross(&up);
        let eye = self.eye();
        #[rustfmt::skip]
        let m = Mat4::new(
            right.x, right.y, right.z, -right.dot(&eye),
            up.x,    up.y,    up.z,    -up.dot(&eye),
            back.x,  back.y,  back.z,  -back.dot(&eye),
            0.0,     0.0,     0.0,     1.0,
        );
        m
    }

    /// `clip_from_view`: reversed-Z infinite perspective for an `aspect` = width / height
    /// viewport (wgpu depth range 0..1, depth 1 at the near plane).
    pub fn clip_from_view(&self, aspect: f32) -> Mat4 {
        let aspect = if aspect.is_finite() && aspect > 1e-6 {
            aspect
        } else {
            1.0
        };
        let f = 1.0 / (self.fov_y_rad * 0.5).tan();
        #[rustfmt::skip]
        let m = Mat4::new(
            f / aspect, 0.0, 0.0,         0.0,
            0.0,        f,   0.0,         0.0,
            0.0,        0.0, 0.0,         self.near_m,
            0.0,        0.0, -1.0,        0.0,
        );
        m
    }

    /// `clip_from_world = clip_from_view * view_from_world`.
    pub fn clip_from_world(&self, aspect: f32) -> Mat4 {
        self.clip_from_view(aspect) * self.view_from_world()
    }

    /// Clamps every field into its documented range, replacing non-finite values.
    fn sanitize(&mut self) {
        if !self.target.iter().all(|v| v.is_finite()) {
            self.target = Vec3::zeros();
        }
        if !self.yaw_rad.is_finite() {
            self.yaw_rad = 0.0;
        }
        self.pitch_rad = if self.pitch_rad.is_finite() {
            self.pitch_rad.clamp(-MAX_PITCH_RAD, MAX_PITCH_RAD)
        } else {
            0.0
        };
        self.distance_m = if self.distance_m.is_finite() {
            self.distance_m.clamp(MIN_DISTANCE_M, MAX_DISTANCE_M)
        } else {
            3.0
        };
        if !(self.fov_y_rad.is_finite() && self.fov_y_rad > 0.01 && self.fov_y_rad < 3.0) {
            self.fov_y_rad = 40f32.to_radians();
        }
        if !(self.near_m.is_finite() && self.near_m > 0.0) {
            self.near_m = 0.02;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn project(cam: &OrbitCamera, p: Vec3) -> Vec3 {
        let c = cam.clip_from_world(1.5) * p.push(1.0);
        Vec3::new(c.x / c.w, c.y / c.w, c.z / c.w)
    }

    #[test]
    fn target_projects_to_centre_and_depth_is_reversed() {
        let cam = OrbitCamera::new(Vec3::new(0.3, 1.0, -0.2), 0.7, 0.3, 2.5);
        let ndc = project(&cam, cam.target);
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5, "{ndc:?}");
        let near_depth = cam.near_m / cam.distance_m;
        assert!((ndc.z - near_depth).abs() < 1e-5);
        // A point further away has a smaller depth value.
        let (right, up) = cam.right_up();
        let back = right.cross(&up);
        let far = project(&cam, cam.target - back * 3.0);
        assert!(far.z < ndc.z && far.z > 0.0);
    }

    #[test]
    fn up_on_screen_is_world_up_for_level_camera() {
        let cam = OrbitCamera::new(Vec3::zeros(), 0.0, 0.0, 2.0);
        assert!((cam.eye() - Vec3::new(0.0, 0.0, 2.0)).norm() < 1e-6);
        let above = project(&cam, Vec3::new(0.0, 0.5, 0.0));
        let right = project(&cam, Vec3::new(0.5, 0.0, 0.0));
        assert!(above.y > 0.1 && above.x.abs() < 1e-6);
        assert!(right.x > 0.1 && right.y.abs() < 1e-6);
    }

    #[test]
    fn pan_zoom_orbit_then_reset_restores_home() {
        let mut cam = OrbitCamera::default();
        let home = cam;
        cam.orbit(1.0, 5.0);
        assert!(cam.pitch_rad <= MAX_PITCH_RAD);
        cam.zoom(0.5);
        cam.pan(100.0, -40.0, 500.0);
        cam.zoom(f32::NAN);
        assert!(cam.target != home.target && cam.distance_m < home.distance_m);
        cam.reset();
        assert_eq!(cam, home);
    }

    #[test]
    fn pan_moves_target_by_one_viewport_for_full_drag() {
        let mut cam = OrbitCamera::new(Vec3::zeros(), 0.0, 0.0, 2.0);
        let half_height = 2.0 * (cam.fov_y_rad * 0.5).tan();
        cam.pan(0.0, 400.0, 400.0);
        assert!(
            (cam.target.y - 2.0 * half_height).abs() < 1e-4,
            "{:?}",
            cam.target
        );
    }

    #[test]
    fn framing_keeps_box_in_view() {
        let lo = Vec3::new(-0.4, 0.0, -0.2);
        let hi = Vec3::new(0.4, 1.8, 0.3);
        let cam = OrbitCamera::framing(lo, hi);
        for corner in 0..8 {
            let p = Vec3::new(
                if corner & 1 == 0 { lo.x } else { hi.x },
                if corner & 2 == 0 { lo.y } else { hi.y },
                if corner & 4 == 0 { lo.z } else { hi.z },
            );
            let ndc = project(&cam, p);
            assert!(
                ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0 && ndc.z > 0.0,
                "{corner}: {ndc:?}"
            );
        }
        let mut unchanged = cam;
        unchanged.frame_bounds(hi, lo);
        assert_eq!(unchanged, cam);
    }
}
