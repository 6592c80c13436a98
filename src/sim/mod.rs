//! Stage 2b, simulation: the ripples characters make, stepped frame by frame through the timeline.
//! Receives the ripple settings and, per frame, the characters' column occupancy (see
//! [`coupling`]); returns the [`RippleState`] at any frame, from memory, from an on-disk
//! checkpoint (see [`checkpoint`]) or by stepping from the nearest earlier state: the state at a
//! frame is the same bits whichever way it was reached.
//!
//! The ripple state at the timeline's first frame is calm water; the step from frame `f - 1` to
//! `f` integrates the waves exactly over that frame interval (see [`spectral`]) with the
//! displacement of the occupancy change between the two frames as a source spread evenly over it.

pub mod checkpoint;
pub mod coupling;
#[cfg(test)]
mod physics_tests;
pub mod ripple_bounds;
pub mod ripples;
pub mod spectral;
#[cfg(test)]
mod wake_tests;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

pub use checkpoint::{CheckpointError, CheckpointKey, CheckpointStore, KeyHasher};
pub use ripples::{Border, RippleField, RippleSettings, RippleState, SumHeightField};
pub use spectral::{Dispersion, RippleStepper};

/// How many recent states the simulation keeps in memory (a frame and the one before it are
/// what a render asks for; a few more make scrubbing back cheap).
const STATES_KEPT: usize = 4;

/// A state kept in memory, with the occupancy of its frame when it was computed (stepping on
/// from it then needs no new occupancy of that frame).
#[derive(Clone)]
struct Kept {
    state: Arc<RippleState>,
    occupancy: Option<Arc<Vec<f32>>>,
}

/// The ripple simulation of one scene.
pub struct Simulation {
    stepper: RippleStepper,
    /// Scales the displacement bodies cause (1 = the displaced volume).
    strength: f64,
    first_frame: u32,
    /// What checkpoints of this simulation are keyed by.
    key: CheckpointKey,
    store: OnceLock<CheckpointStore>,
    recent: Mutex<BTreeMap<u32, Kept>>,
    /// Frames stepped (not read) since creation: how much work checkpoints saved.
    stepped: AtomicU64,
}

/// Where [`Simulation::state_at`] would start from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateSource {
    Memory,
    Checkpoint(u32),
    Calm,
}

impl Simulation {
    pub fn new(
        settings: RippleSettings,
        strength: f64,
        first_frame: u32,
        fps: f64,
        key: CheckpointKey,
    ) -> Self {
        Simulation {
            stepper: RippleStepper::new(settings, 1.0 / fps),
            strength,
            first_frame,
            key,
            store: OnceLock::new(),
            recent: Mutex::new(BTreeMap::new()),
            stepped: AtomicU64::new(0),
        }
    }

    pub fn settings(&self) -> &RippleSettings {
        self.stepper.settings()
    }

    /// Reads and writes checkpoints under `out_dir` from now on (see [`CheckpointStore::open`]);
    /// returns the folders of older versions of `scene_stem` it deleted. A simulation keeps the first store
    /// it opens: later calls do nothing.
    pub fn open_store(
        &self,
        out_dir: &Path,
        scene_stem: &str,
    ) -> Result<Vec<PathBuf>, CheckpointError> {
        if self.store.get().is_some() {
            return Ok(Vec::new());
        }
        let store = CheckpointStore::open(out_dir, scene_stem, self.key)?;
        let removed = store.removed_stale.clone();
        // A racing call may have set one first; both are the same folder.
        let _ = self.store.set(store);
        Ok(removed)
    }

    pub fn store(&self) -> Option<&CheckpointStore> {
        self.store.get()
    }

    /// Frames stepped so far (each one an occupancy and a frame of substeps).
    pub fn frames_stepped(&self) -> u64 {
        self.stepped.load(Ordering::Relaxed)
    }

    /// The latest state in memory at or before `frame`.
    fn remembered(&self, frame: u32) -> Option<(u32, Kept)> {
        let recent = self.recent.lock().unwrap();
        recent
            .range(..=frame)
            .next_back()
            .map(|(&f, kept)| (f, kept.clone()))
    }

    /// The latest valid checkpoint in `after + 1..=frame` (only those are read).
    fn checkpoint_after(&self, after: Option<u32>, frame: u32) -> Option<(u32, RippleState)> {
        let from = after.map_or(self.first_frame, |f| f + 1);
        self.store.get()?.latest_in(from..=frame, self.settings())
    }

    /// The ripple state at `frame` (>= the first frame). `occupancy(f)` must return the
    /// characters' occupancy at frame `f` (see [`coupling::occupancy`]); it is called for the
    /// frames stepped through. Starts from the latest of: a state in memory, a checkpoint, calm
    /// water at the first frame. Checkpoints of the frames stepped are written when a store is set.
    pub fn state_at(
        &self,
        frame: u32,
        occupancy: &dyn Fn(u32) -> Vec<f32>,
    ) -> Result<Arc<RippleState>, CheckpointError> {
        let frame = frame.max(self.first_frame);
        let remembered = self.remembered(frame);
        if let Some((f, kept)) = &remembered {
            if *f == frame {
                return Ok(kept.state.clone());
            }
        }
        let checkpoint = self.checkpoint_after(remembered.as_ref().map(|(f, _)| *f), frame);
        let (mut at, mut state, kept_occupancy) = match (checkpoint, remembered) {
            (Some((f, loaded)), _) => (f, loaded, None),
            (None, Some((f, kept))) => (f, (*kept.state).clone(), kept.occupancy),
            (None, None) => {
                let calm = RippleState::calm(*self.settings());
                self.save(self.first_frame, &calm)?;
                (self.first_frame, calm, None)
            }
        };
        // The occupancy of the frame `state` is at: needed only to step on from it.
        let mut occupancy_at = kept_occupancy;
        while at < frame {
            let before = occupancy_at.unwrap_or_else(|| Arc::new(occupancy(at)));
            let after = Arc::new(occupancy(at + 1));
            let push = coupling::displacement(self.settings(), &before, &after, self.strength);
            self.stepper.advance_frame(&mut state, &push);
            at += 1;
            self.stepped.fetch_add(1, Ordering::Relaxed);
            self.save(at, &state)?;
            occupancy_at = Some(after);
        }
        let state = Arc::new(state);
        let mut recent = self.recent.lock().unwrap();
        recent.insert(
            frame,
            Kept {
                state: state.clone(),
                occupancy: occupancy_at,
            },
        );
        while recent.len() > STATES_KEPT {
            let oldest = *recent.keys().next().unwrap();
            recent.remove(&oldest);
        }
        Ok(state)
    }

    /// Which source `state_at(frame)` would start from.
    pub fn source_for(&self, frame: u32) -> StateSource {
        let remembered = self.remembered(frame).map(|(f, _)| f);
        if remembered == Some(frame) {
            return StateSource::Memory;
        }
        match self.checkpoint_after(remembered, frame) {
            Some((f, _)) => StateSource::Checkpoint(f),
            None if remembered.is_some() => StateSource::Memory,
            None => StateSource::Calm,
        }
    }

    fn save(&self, frame: u32, state: &RippleState) -> Result<(), CheckpointError> {
        match self.store.get() {
            Some(store) if !store.has(frame) => store.save(frame, state),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> RippleSettings {
        RippleSettings {
            damping_per_s: 0.3,
            depth_m: 0.3,
            ..spectral::tests::settings(48, 32, 0.05)
        }
    }

    /// A body bobbing through the surface at a moving place: occupancy changes every frame.
    fn occupancy(frame: u32) -> Vec<f32> {
        let s = settings();
        let mut o = vec![0.0f32; s.node_count()];
        let ix = 10 + (frame as usize % 25);
        let iz = 16;
        o[iz * 48 + ix] = 0.02 * (1.0 + (frame as f32 * 0.7).sin());
        o
    }

    #[test]
    fn a_frame_is_the_same_reached_from_the_start_from_memory_or_from_a_checkpoint() {
        let dir = tempfile::tempdir().unwrap();
        let key = KeyHasher::new("test").input("scene", b"x").finish();
        let simulation = || Simulation::new(settings(), 1.0, 1, 24.0, key);
        let full = simulation();
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let counted = |f: u32| {
            calls.fetch_add(1, Ordering::Relaxed);
            occupancy(f)
        };
        let straight: Vec<Arc<RippleState>> = (1..=30)
            .map(|f| full.state_at(f, &counted).unwrap())
            .collect();
        // Frame by frame, each frame's occupancy is computed once.
        assert_eq!(calls.load(Ordering::Relaxed), 30);
        assert!(
            straight[29].max_abs_height_m() > 0.0,
            "the body made ripples"
        );

        // Alone, from calm water, jumping straight to frame 30.
        let alone = simulation();
        assert_eq!(*alone.state_at(30, &occupancy).unwrap(), *straight[29]);

        // Through checkpoints: a first run writes them, a second reads frame 20's and steps on.
        let with_store = || {
            let s = simulation();
            s.open_store(dir.path(), "s").unwrap();
            s
        };
        with_store().state_at(20, &occupancy).unwrap();
        // A state read from its own checkpoint needs no occupancy at all.
        let untouched = |_: u32| -> Vec<f32> { panic!("nothing to step") };
        assert_eq!(
            *with_store().state_at(20, &untouched).unwrap(),
            *straight[19]
        );
        let second = with_store();
        assert_eq!(second.source_for(26), StateSource::Checkpoint(20));
        assert_eq!(*second.state_at(26, &occupancy).unwrap(), *straight[25]);
        assert_eq!(
            second.frames_stepped(),
            6,
            "resumed from frame 20, not recomputed"
        );
        // An exact checkpoint hit steps nothing.
        let third = with_store();
        assert_eq!(*third.state_at(24, &occupancy).unwrap(), *straight[23]);
        assert_eq!(third.frames_stepped(), 0);
        // Backwards from memory: an earlier frame than the cached ones is recomputed correctly.
        assert_eq!(*full.state_at(3, &occupancy).unwrap(), *straight[2]);
    }
}
