//! snell: objects seen through moving water, rendered with the geometric refraction method of
//! Schmidt's thesis (refraction cells and virtual vertices), done exactly and flagged where it fails.
//!
//! The stages, in the order a frame flows through them:
//! 0. [`scene`]      — scene file (TOML) -> validated [`scene::Scene`]; built-in primitives -> world meshes, textures.
//!    [`character`] — glTF characters: load, sample an animation, skin (pure CPU, rayon) -> world meshes.
//! 1. [`timeline`]   — frame <-> time, camera keyframe tracks.
//! 2. [`water`]      — the water membrane at time t: analytic waves, height field, triangulated grid.
//!    [`sim`]        — the ripples characters make (damped wave equation), stepped and checkpointed.
//! 3. [`refraction`] — refraction rays, cells, sight-facet search, virtual vertices, flags (pure CPU, rayon).
//! 4. [`gpu`]        — wgpu passes: true geometry, stencil of visible water, virtual geometry, Fresnel sky.
//!    [`reference`]  — the ray-traced reference over the same stage-2 output (CPU, rayon): `--method raytrace`.
//! 5. [`output`]     — multi-layer OpenEXR frames, per-frame report, tone-mapped previews, image comparison.
//!
//! [`vessel`] moves vertices seen through glass panes and cylinders (Mukai et al.'s vertex
//! displacement; pure CPU): every wall path of a point and its displaced vertex.
//!
//! [`accuracy`] reproduces the thesis's accuracy study (error volumes of its Tables 4.1, 4.2, 4.5)
//! for the linear and the exact method.
//!
//! [`check`] compares frames (EXR files, or a scene's renders against goldens) for CI: FLIP,
//! Z/P tolerances, exact flag counts, JUnit.
//!
//! [`chart`] measures speed against accuracy: every method and membrane resolution timed and
//! compared with the ray-traced reference (`snell chart`), and a scene's `max_error_px` budget.
//!
//! [`tools`] checks snell from outside: every image of given points (`snell locate`), position
//! error between frames (`snell compare`), a frame's geometry and camera for other tools (`snell export`).
//!
//! [`oracle`] finds every image of a point by a scan that provably misses none, sharing only the
//! surface's height function with the renderer: the truth the methods are checked against.
//!
//! [`seeded`] is the one seeded random number generator of the tests and benchmarks.
//!
//! [`frame`] ties the stages together: one `render_frame` entry point used identically by the CLI
//! and by the tests. [`interrupt`] turns Ctrl-C into a stop after the frame in flight.

#[macro_use]
pub mod console;
pub mod accuracy;
pub mod camera;
pub mod character;
pub mod chart;
pub mod check;
pub mod color;
pub mod draw;
pub mod farm;
pub mod files;
pub mod frame;
pub mod gpu;
pub mod interrupt;
pub mod mesh;
pub mod oracle;
pub mod output;
pub mod panics;
pub mod preview;
pub mod reference;
pub mod refraction;
pub mod scene;
pub mod seeded;
pub mod sim;
pub mod stability;
pub mod stats;
pub mod timeline;
pub mod tools;
pub mod vessel;
pub mod water;

/// The version written into every EXR header and report.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
