//! The ray-traced methods inside the render pipeline: [`RenderJob::refract`] stops after the water
//! for them (no refraction field, no virtual geometry, zero flag counts) and keeps what the tracer
//! needs in [`TraceInputs`]; [`RenderJob::render_refracted`] then traces the frame on the CPU with
//! [`crate::reference`] instead of drawing it on the GPU.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use super::{RefractedFrame, RenderJob, SnellError};
use crate::camera::Camera;
use crate::draw::{FrameDraw, FrameView};
use crate::mesh::Object;
use crate::reference::{self, texture::TextureSet, TraceScene, TracedFrame};
use crate::refraction::flags::{FlagCounts, TrackingState};
use crate::sim::{RippleState, SumHeightField};
use crate::water::{Membrane, WaterSurface};

/// One frame's stage-2 output as the tracer needs it (the static objects stay in the job).
pub struct TraceInputs {
    /// The characters posed at the frame's time.
    pub posed: Vec<Object>,
    /// The waves frozen at the frame's time.
    pub waves: WaterSurface,
    pub ripples: Option<Arc<RippleState>>,
    pub membrane: Membrane,
}

/// The job's textures for the tracer, or why they cannot be used.
pub(super) type TracedTextures = Result<TextureSet, String>;

impl RenderJob {
    /// The CPU stages' result for a ray-traced frame: the membrane (the GPU's `draw` carries it
    /// too, for tools that read it), the materials, no virtual geometry and no flags.
    pub(super) fn traced_frame(
        &self,
        frame: u32,
        time_secs: f64,
        camera: Camera,
        image_size: (u32, u32),
        inputs: TraceInputs,
        stage_secs: BTreeMap<String, f64>,
    ) -> RefractedFrame {
        let draw = FrameDraw {
            membrane_vertices: super::membrane_vertices(&inputs.membrane),
            membrane_indices: inputs
                .membrane
                .triangles
                .iter()
                .flatten()
                .copied()
                .collect(),
            materials: super::draw_materials(self.objects.iter().chain(&inputs.posed)),
            ..FrameDraw::default()
        };
        RefractedFrame {
            frame,
            time_secs,
            camera,
            draw,
            view: FrameView {
                camera,
                previous_camera: camera,
                lighting: self.scene.lighting(),
                water: self.scene.water_optics(),
            },
            counts: FlagCounts::default(),
            image_size,
            tracking: TrackingState {
                grid: inputs.membrane.grid,
                image_size,
                vertices: Vec::new(),
                camera,
                drawn_positions: Vec::new(),
                true_positions: Vec::new(),
            },
            stage_secs,
            trace: Some(inputs),
        }
    }

    /// Traces `refracted` (made by [`RenderJob::refract`] for a ray-traced method) at
    /// `width` x `height`: the layers, the object seen per pixel, and the tracer's counts.
    pub fn trace_refracted(
        &self,
        refracted: &RefractedFrame,
        width: u32,
        height: u32,
    ) -> Result<TracedFrame, SnellError> {
        let (Some(inputs), Some(water_model)) = (&refracted.trace, self.method.traced_water())
        else {
            return Err(SnellError::Argument(format!(
                "frame {} was prepared for method {}, which is not ray-traced",
                refracted.frame,
                self.method.name()
            )));
        };
        let textures = self
            .traced_textures
            .get_or_init(|| TextureSet::new(&self.textures).map_err(|e| e.to_string()))
            .as_ref()
            .map_err(|problem| SnellError::Frame {
                scene: self.scene.path.clone(),
                frame: refracted.frame,
                problem: problem.clone(),
            })?;
        let ripples = inputs.ripples.as_ref().map(|state| state.field());
        let field = SumHeightField {
            base: &inputs.waves,
            ripples,
        };
        let scene = TraceScene {
            objects: self.objects.iter().chain(&inputs.posed).collect(),
            materials: &refracted.draw.materials,
            textures,
            surface: crate::refraction::surface::of_water(
                &inputs.waves,
                ripples,
                &field,
                inputs.membrane.grid,
            ),
            membrane: &inputs.membrane,
            view: refracted.view,
            water_model,
            grid: self.scene.antialias.reference_grid,
        };
        let clock = Instant::now();
        let traced = reference::trace_frame(&scene, width, height);
        log::debug!(
            "traced frame {} at {width}x{height}: {} refracted rays, {:.1} ms",
            refracted.frame,
            traced.stats.refracted_rays,
            clock.elapsed().as_secs_f64() * 1e3
        );
        Ok(traced)
    }
}
