//! Measuring devices as planning sees them: the camera rig and the laser tracker, what each can
//! measure and how well.

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Matrix6, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::geometry::Pose;
use crate::safety::ObstacleBox;

/// Why a device cannot measure the target at a pose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Unmeasurable {
    /// Short reason used for counting (`camera 'left': outside the image`).
    pub reason: String,
    /// The numbers behind it.
    pub detail: String,
}

impl std::fmt::Display for Unmeasurable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.reason, self.detail)
    }
}

/// A measuring device as planning sees it: where the target can be measured, and how well.
pub trait MeasuringDevice: Send + Sync {
    /// Name used in reports.
    fn name(&self) -> String;

    /// `T_device_base`: the frame the device reports positions in.
    fn t_device_base(&self) -> Pose;

    /// The measured point (target origin or reflector) in the tool frame.
    fn measured_point_in_tool_m(&self) -> Vector3<f64>;

    /// Whether the target can be measured with the tool at `t_base_tool`.
    fn check(&self, t_base_tool: &Pose) -> std::result::Result<(), Unmeasurable>;

    /// Covariance (device frame, m^2) of the measured point's position at `t_base_tool`.
    fn position_covariance(&self, t_base_tool: &Pose) -> Result<Matrix3<f64>>;
}

/// A pixel projection of a camera-frame point (`None` when it does not project).
pub type ProjectFn = dyn Fn(&Point3<f64>) -> Option<Point2<f64>> + Send + Sync;

/// One camera: its placement, image size and projection (any lens model, supplied as a
/// function so that this crate needs no camera library).
#[derive(Clone)]
pub struct CameraView {
    /// Name used in messages.
    pub name: String,
    /// `T_base_cam` (camera z forward, x right, y down).
    pub t_base_cam: Pose,
    /// Image width, pixels (the image spans `[-0.5, width - 0.5]`).
    pub width_px: f64,
    /// Image height, pixels.
    pub height_px: f64,
    project: Arc<ProjectFn>,
}

impl std::fmt::Debug for CameraView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CameraView")
            .field("name", &self.name)
            .field("t_base_cam", &self.t_base_cam)
            .field("width_px", &self.width_px)
            .field("height_px", &self.height_px)
            .finish_non_exhaustive()
    }
}

impl CameraView {
    /// A camera with its own projection function (pixel-centre convention).
    pub fn new(
        name: impl Into<String>,
        t_base_cam: Pose,
        width_px: u32,
        height_px: u32,
        project: impl Fn(&Point3<f64>) -> Option<Point2<f64>> + Send + Sync + 'static,
    ) -> Self {
        Self {
            name: name.into(),
            t_base_cam,
            width_px: width_px as f64,
            height_px: height_px as f64,
            project: Arc::new(project),
        }
    }

    /// A distortion-free pinhole camera.
    #[allow(clippy::too_many_arguments)]
    pub fn pinhole(
        name: impl Into<String>,
        t_base_cam: Pose,
        fx_px: f64,
        fy_px: f64,
        cx_px: f64,
        cy_px: f64,
        width_px: u32,
        height_px: u32,
    ) -> Self {
        Self::new(name, t_base_cam, width_px, height_px, move |p: &Point3<f64>| {
            (p.z > 1e-9).then(|| Point2::new(fx_px * p.x / p.z + cx_px, fy_px * p.y / p.z + cy_px))
        })
    }

    /// `T_base_cam` of a camera at `position_m` whose optical axis passes through `look_at_m`,
    /// with `up` appearing up in the image.
    pub fn look_at(position_m: [f64; 3], look_at_m: [f64; 3], up: [f64; 3]) -> Result<Pose> {
        let pos = Vector3::from(position_m);
        let z = Vector3::from(look_at_m) - pos;
        let up = Vector3::from(up);
        if z.norm() < 1e-9 || z.cross(&up).norm() < 1e-9 * z.norm() * up.norm().max(1e-300) {
            return Err(RobotError::Safety(
                "camera: look_at_m must differ from position_m and not lie along up".into(),
            ));
        }
        let z = z.normalize();
        let x = z.cross(&up).normalize();
        let y = z.cross(&x);
        let rot = Rotation3::from_basis_unchecked(&[x, y, z]);
        Ok(Isometry3::from_parts(Translation3::from(pos), UnitQuaternion::from_rotation_matrix(&rot)))
    }

    /// Pixel of a camera-frame point.
    pub fn project_cam(&self, p_cam: &Point3<f64>) -> Option<Point2<f64>> {
        if p_cam.z <= 1e-9 {
            return None;
        }
        (self.project)(p_cam).filter(|px| px.x.is_finite() && px.y.is_finite())
    }

    /// Whether a pixel lies at least `border_px` inside the image.
    pub fn inside(&self, px: &Point2<f64>, border_px: f64) -> bool {
        px.x >= -0.5 + border_px
            && px.x <= self.width_px - 0.5 - border_px
            && px.y >= -0.5 + border_px
            && px.y <= self.height_px - 0.5 - border_px
    }
}

/// The planar target's geometry in the target frame (z = 0, normal +z).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetShape {
    /// Outline of the plate (must project inside every image).
    pub outline_m: Vec<Point3<f64>>,
    /// Dark features (polygons) whose projected sides must be long enough.
    pub features_m: Vec<Vec<Point3<f64>>>,
    /// Corner points measured in the image (the pose estimation's observations).
    pub corners_m: Vec<Point3<f64>>,
}

impl TargetShape {
    /// From a 2D outline, 2D feature polygons and corner points (all target frame, metres).
    pub fn new(outline_m: &[Point2<f64>], features_m: &[Vec<Point2<f64>>], corners_m: &[Point3<f64>]) -> Self {
        let lift = |p: &Point2<f64>| Point3::new(p.x, p.y, 0.0);
        Self {
            outline_m: outline_m.iter().map(lift).collect(),
            features_m: features_m.iter().map(|f| f.iter().map(lift).collect()).collect(),
            corners_m: corners_m.to_vec(),
        }
    }

    /// The source's plate: the five black squares (side `square_m`) of a 3x3 checkerboard,
    /// with a white margin.
    pub fn plate(square_m: f64, margin_m: f64) -> Self {
        let half = 1.5 * square_m + margin_m;
        let outline =
            [Point2::new(-half, -half), Point2::new(half, -half), Point2::new(half, half), Point2::new(-half, half)];
        let mut features = Vec::new();
        let mut corners = Vec::new();
        for row in 0..3 {
            for col in 0..3 {
                if (row + col) % 2 != 0 {
                    continue;
                }
                let x0 = (col as f64 - 1.5) * square_m;
                let y1 = (1.5 - row as f64) * square_m;
                let sq = vec![
                    Point2::new(x0, y1),
                    Point2::new(x0 + square_m, y1),
                    Point2::new(x0 + square_m, y1 - square_m),
                    Point2::new(x0, y1 - square_m),
                ];
                corners.extend(sq.iter().map(|p| Point3::new(p.x, p.y, 0.0)));
                features.push(sq);
            }
        }
        Self::new(&outline, &features, &corners)
    }

    /// Radius of the outline's bounding circle about the target origin.
    pub fn radius_m(&self) -> f64 {
        self.outline_m.iter().map(|p| p.coords.norm()).fold(0.0, f64::max)
    }
}

/// What a camera must see (TOML table `[measure]` of a plan file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VisibilitySettings {
    /// Shortest projected side of any dark feature, pixels.
    #[serde(default = "default_min_feature_px")]
    pub min_feature_px: f64,
    /// Largest angle between the viewing ray and the target normal, degrees.
    #[serde(default = "default_view_angle")]
    pub max_view_angle_deg: f64,
    /// Distance the outline must keep from the image border, pixels.
    #[serde(default = "default_border")]
    pub border_px: f64,
    /// Corner noise per image axis, pixels (one standard deviation).
    #[serde(default = "default_sigma_px")]
    pub sigma_px: f64,
    /// Cameras that must see the target (default: all).
    #[serde(default)]
    pub min_cameras: Option<usize>,
}

fn default_min_feature_px() -> f64 {
    15.0
}
fn default_view_angle() -> f64 {
    60.0
}
fn default_border() -> f64 {
    10.0
}
fn default_sigma_px() -> f64 {
    0.1
}

impl Default for VisibilitySettings {
    fn default() -> Self {
        Self {
            min_feature_px: default_min_feature_px(),
            max_view_angle_deg: default_view_angle(),
            border_px: default_border(),
            sigma_px: default_sigma_px(),
            min_cameras: None,
        }
    }
}

/// What one or more cameras photographing a target on the tool can see, as planning needs it
/// (the calibrated cameras themselves are `ferrocal_vision::pose::CameraRig`).
#[derive(Clone, Debug)]
pub struct CameraVisibility {
    /// The cameras; the first one's frame is the device frame.
    pub cameras: Vec<CameraView>,
    /// The target.
    pub target: TargetShape,
    /// `T_tool_target`.
    pub t_tool_target: Pose,
    /// Visibility requirements and corner noise.
    pub settings: VisibilitySettings,
    /// Boxes that block the line of sight (usually the safety configuration's obstacles).
    pub occluders: Vec<ObstacleBox>,
}

impl CameraVisibility {
    /// A rig; checks the settings.
    pub fn new(
        cameras: Vec<CameraView>,
        target: TargetShape,
        t_tool_target: Pose,
        settings: VisibilitySettings,
        occluders: Vec<ObstacleBox>,
    ) -> Result<Self> {
        let bad = |m: String| Err(RobotError::Safety(format!("camera rig: {m}")));
        if cameras.is_empty() {
            return bad("no camera".into());
        }
        if target.outline_m.len() < 3 || target.corners_m.is_empty() {
            return bad("the target needs an outline of at least 3 points and at least one corner".into());
        }
        let s = &settings;
        for (v, n) in [(s.min_feature_px, "min_feature_px"), (s.border_px, "border_px")] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{n} must be finite and >= 0, got {v}"));
            }
        }
        if !(s.sigma_px.is_finite() && s.sigma_px > 0.0) {
            return bad(format!("sigma_px must be > 0, got {}", s.sigma_px));
        }
        if !(s.max_view_angle_deg.is_finite() && s.max_view_angle_deg > 0.0 && s.max_view_angle_deg <= 90.0) {
            return bad(format!("max_view_angle_deg must lie in (0, 90], got {}", s.max_view_angle_deg));
        }
        if let Some(m) = s.min_cameras {
            if m == 0 || m > cameras.len() {
                return bad(format!("min_cameras must lie in 1..={}, got {m}", cameras.len()));
            }
        }
        Ok(Self { cameras, target, t_tool_target, settings, occluders })
    }

    fn t_base_target(&self, t_base_tool: &Pose) -> Pose {
        t_base_tool * self.t_tool_target
    }

    /// Whether camera `cam` sees the whole target at `t_base_target`.
    fn camera_sees(&self, cam: &CameraView, t_base_target: &Pose) -> std::result::Result<(), Unmeasurable> {
        let who = format!("camera '{}'", cam.name);
        let fail = |what: &str, detail: String| Err(Unmeasurable { reason: format!("{who}: {what}"), detail });
        let t_cam_target = cam.t_base_cam.inverse() * t_base_target;
        let centre = t_cam_target.translation.vector;
        let normal = t_cam_target.rotation * Vector3::z();
        if centre.norm() < 1e-9 {
            return fail("target at the camera", "the target origin coincides with the camera centre".into());
        }
        let cos = normal.dot(&(-centre)) / centre.norm();
        let angle_deg = cos.clamp(-1.0, 1.0).acos().to_degrees();
        if cos <= 0.0 {
            return fail("target seen from behind", format!("viewing angle {angle_deg:.1} deg"));
        }
        if angle_deg > self.settings.max_view_angle_deg {
            return fail(
                "viewing angle too large",
                format!("{angle_deg:.1} deg > {:.1} deg", self.settings.max_view_angle_deg),
            );
        }
        for p in &self.target.outline_m {
            let pc = t_cam_target * p;
            if pc.z <= 1e-6 {
                return fail("target behind the camera", format!("outline point at depth {:.3} m", pc.z));
            }
            match cam.project_cam(&pc) {
                Some(px) if cam.inside(&px, self.settings.border_px) => {}
                Some(px) => {
                    return fail(
                        "target outside the image",
                        format!(
                            "outline point at ({:.0}, {:.0}) px, image {}x{} px with a {:.0} px border",
                            px.x, px.y, cam.width_px, cam.height_px, self.settings.border_px
                        ),
                    )
                }
                None => return fail("target outside the image", "an outline point does not project".into()),
            }
        }
        let mut smallest = f64::INFINITY;
        for f in &self.target.features_m {
            let px: Vec<Point2<f64>> = f.iter().filter_map(|p| cam.project_cam(&(t_cam_target * p))).collect();
            if px.len() != f.len() {
                return fail("feature does not project", "a feature corner does not project".into());
            }
            for k in 0..px.len() {
                smallest = smallest.min((px[(k + 1) % px.len()] - px[k]).norm());
            }
        }
        if smallest < self.settings.min_feature_px {
            return fail(
                "features too small",
                format!("shortest feature side {smallest:.1} px < {:.1} px", self.settings.min_feature_px),
            );
        }
        let eye = Point3::from(cam.t_base_cam.translation.vector);
        let sight: Vec<Point3<f64>> = std::iter::once(Point3::origin())
            .chain(self.target.outline_m.iter().copied())
            .map(|p| t_base_target * p)
            .collect();
        for o in &self.occluders {
            if sight.iter().any(|p| segment_hits_box(&eye, p, o)) {
                return fail(&format!("line of sight blocked by '{}'", o.name), format!("obstacle '{}'", o.name));
            }
        }
        Ok(())
    }

    /// Fisher information (6x6, per (translation, rotation) of the target about its origin in
    /// the device frame) of the corners seen by camera `cam`.
    fn camera_information(&self, cam: &CameraView, t_base_target: &Pose) -> Result<Matrix6<f64>> {
        let t_dev_base = self.t_device_base();
        let t_cam_dev = cam.t_base_cam.inverse() * t_dev_base.inverse();
        let t_dev_target = t_dev_base * t_base_target;
        let origin = t_dev_target.translation.vector;
        let r_cam_dev = t_cam_dev.rotation.to_rotation_matrix();
        let s2 = self.settings.sigma_px * self.settings.sigma_px;
        let mut info = Matrix6::zeros();
        let h = 1e-6;
        for c in &self.target.corners_m {
            let p_dev = t_dev_target * c;
            let p_cam = t_cam_dev * p_dev;
            // d(pixel)/d(p_cam) by central differences of the projection.
            let mut jp = nalgebra::Matrix2x3::zeros();
            for k in 0..3 {
                let mut a = p_cam;
                let mut b = p_cam;
                a[k] += h;
                b[k] -= h;
                let (Some(pa), Some(pb)) = (cam.project_cam(&a), cam.project_cam(&b)) else {
                    return Err(RobotError::Safety(format!(
                        "camera '{}': a target corner does not project; cannot compute the measurement noise",
                        cam.name
                    )));
                };
                jp.set_column(k, &((pa - pb) / (2.0 * h)));
            }
            // d(p_dev)/d(xi) = [I, -[p_dev - origin]x].
            let lever = p_dev.coords - origin;
            let mut dp = nalgebra::Matrix3x6::zeros();
            dp.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
            dp.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-crate::geometry::skew(&lever)));
            let j = jp * r_cam_dev.matrix() * dp;
            info += j.transpose() * j / s2;
        }
        Ok(info)
    }
}

impl MeasuringDevice for CameraVisibility {
    fn name(&self) -> String {
        let names: Vec<&str> = self.cameras.iter().map(|c| c.name.as_str()).collect();
        format!("camera{} {}", if names.len() > 1 { "s" } else { "" }, names.join(" + "))
    }

    fn t_device_base(&self) -> Pose {
        self.cameras[0].t_base_cam.inverse()
    }

    fn measured_point_in_tool_m(&self) -> Vector3<f64> {
        self.t_tool_target.translation.vector
    }

    fn check(&self, t_base_tool: &Pose) -> std::result::Result<(), Unmeasurable> {
        let t = self.t_base_target(t_base_tool);
        let need = self.settings.min_cameras.unwrap_or(self.cameras.len());
        let mut seen = 0;
        let mut first_failure = None;
        for cam in &self.cameras {
            match self.camera_sees(cam, &t) {
                Ok(()) => seen += 1,
                Err(e) => {
                    if first_failure.is_none() {
                        first_failure = Some(e);
                    }
                }
            }
        }
        if seen >= need {
            Ok(())
        } else {
            Err(first_failure.unwrap_or(Unmeasurable {
                reason: "too few cameras see the target".into(),
                detail: format!("{seen} of {need}"),
            }))
        }
    }

    fn position_covariance(&self, t_base_tool: &Pose) -> Result<Matrix3<f64>> {
        let t = self.t_base_target(t_base_tool);
        let mut info = Matrix6::zeros();
        for cam in &self.cameras {
            if self.camera_sees(cam, &t).is_ok() {
                info += self.camera_information(cam, &t)?;
            }
        }
        let inv = info.try_inverse().ok_or_else(|| RobotError::Singular {
            reason: "the cameras do not determine the target pose at this configuration".into(),
        })?;
        let c = inv.fixed_view::<3, 3>(0, 0).into_owned();
        Ok((c + c.transpose()) * 0.5)
    }
}

/// A laser tracker measuring a reflector on the tool.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackerView {
    /// Name used in reports.
    pub name: String,
    /// `T_base_tracker`.
    pub t_base_tracker: Pose,
    /// Usable distance range `[min, max]`, metres.
    pub range_m: [f64; 2],
    /// Constant part of the noise, micrometres per axis (one standard deviation).
    pub sigma_const_um: f64,
    /// Distance-proportional part, micrometres per metre.
    pub sigma_per_m_um: f64,
    /// Reflector position in the tool frame.
    pub reflector_in_tool_m: Vector3<f64>,
    /// Reflector opening axis in the tool frame (None: accepts every direction).
    pub reflector_axis_in_tool: Option<Vector3<f64>>,
    /// Half acceptance angle of the reflector, degrees.
    pub max_incidence_deg: f64,
    /// Boxes that block the line of sight.
    pub occluders: Vec<ObstacleBox>,
}

impl MeasuringDevice for TrackerView {
    fn name(&self) -> String {
        format!("laser tracker '{}'", self.name)
    }

    fn t_device_base(&self) -> Pose {
        self.t_base_tracker.inverse()
    }

    fn measured_point_in_tool_m(&self) -> Vector3<f64> {
        self.reflector_in_tool_m
    }

    fn check(&self, t_base_tool: &Pose) -> std::result::Result<(), Unmeasurable> {
        let who = format!("tracker '{}'", self.name);
        let p = t_base_tool * Point3::from(self.reflector_in_tool_m);
        let eye = Point3::from(self.t_base_tracker.translation.vector);
        let d = (p - eye).norm();
        if d < self.range_m[0] || d > self.range_m[1] {
            return Err(Unmeasurable {
                reason: format!("{who}: out of range"),
                detail: format!("{d:.3} m outside [{:.3}, {:.3}] m", self.range_m[0], self.range_m[1]),
            });
        }
        if let Some(axis) = self.reflector_axis_in_tool {
            let a = t_base_tool.rotation * axis;
            let to_tracker = eye - p;
            let cos = a.dot(&to_tracker) / (a.norm() * to_tracker.norm()).max(1e-300);
            let ang = cos.clamp(-1.0, 1.0).acos().to_degrees();
            if ang > self.max_incidence_deg {
                return Err(Unmeasurable {
                    reason: format!("{who}: reflector turned away"),
                    detail: format!("incidence {ang:.1} deg > {:.1} deg", self.max_incidence_deg),
                });
            }
        }
        for o in &self.occluders {
            if segment_hits_box(&eye, &p, o) {
                return Err(Unmeasurable {
                    reason: format!("{who}: line of sight blocked by '{}'", o.name),
                    detail: format!("obstacle '{}'", o.name),
                });
            }
        }
        Ok(())
    }

    fn position_covariance(&self, t_base_tool: &Pose) -> Result<Matrix3<f64>> {
        let p = t_base_tool * Point3::from(self.reflector_in_tool_m);
        let d = (p.coords - self.t_base_tracker.translation.vector).norm();
        let s = (self.sigma_const_um + self.sigma_per_m_um * d) * 1e-6;
        Ok(Matrix3::identity() * s * s)
    }
}

/// Whether the segment from `a` to `b` passes through the box (the last millimetre before `b`
/// is ignored, so a target resting on a face is not blocked by it).
pub fn segment_hits_box(a: &Point3<f64>, b: &Point3<f64>, o: &ObstacleBox) -> bool {
    let d = b - a;
    let len = d.norm();
    if len < 1e-12 {
        return (0..3).all(|k| a[k] >= o.min_m[k] && a[k] <= o.max_m[k]);
    }
    let t_end = ((len - 1e-3) / len).max(0.0);
    let (mut t0, mut t1) = (0.0f64, t_end);
    for k in 0..3 {
        if d[k].abs() < 1e-15 {
            if a[k] < o.min_m[k] || a[k] > o.max_m[k] {
                return false;
            }
        } else {
            let mut ta = (o.min_m[k] - a[k]) / d[k];
            let mut tb = (o.max_m[k] - a[k]) / d[k];
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}
