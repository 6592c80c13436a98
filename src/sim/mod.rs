//! Stage 2b, simulation: the ripples characters make, stepped frame by frame through the timeline.
//! Receives the ripple settings and, per frame, the characters' column occupancy (see
//! [`coupling`]); returns the [`RippleState`] at any frame, from memory, from an on-disk
//! checkpoint (see [`checkpoint`]) or by stepping from the nearest earlier state: the state at a
//! frame is the same bits whichever way it was reached.
//!
//! The ripple state at the timeline's first frame is calm water; the step from frame `f - 1` to
//! `f` adds the displacement of the occupancy change between the two frames, spread over the
//! substeps of that frame interval.

pub mod checkpoint;
pub mod coupling;
pub mod ripples;

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, OnceLock};

pub use checkpoint::{CheckpointError, CheckpointKey, CheckpointStore, KeyHasher};
pub use ripples::{
    Border, RippleField, RippleSettings, RippleState, RippleStepper, SumHeightField,
};

/// How many recent states the simulation keeps in memory (a frame and the one before it are
/// what a render asks for; a few more make scrubbing back cheap).
const STATES_KEPT: usize = 4;

/// The ripple simulation of one scene.
pub struct Simulation {
    stepper: RippleStepper,
    /// Scales the displacement bodies cause (1 = the displaced volume).
    strength: f64,
    first_frame: u32,
    frame_secs: f64,
    store: OnceLock<CheckpointStore>,
    recent: Mutex<BTreeMap<u32, Arc<RippleState>>>,
    /// Frames stepped (not read) since creation: how much work checkpoints saved, for reports.
    stepped: Mutex<u64>,
}

/// Where [`Simulation::state_at`] got a state from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateSource {
    Memory,
    Checkpoint(u32),
    Calm,
}

impl Simulation {
    pub fn new(settings: RippleSettings, strength: f64, first_frame: u32, fps: f64) -> Self {
        Simulation {
            stepper: RippleStepper::new(settings),
            strength,
            first_frame,
            frame_secs: 1.0 / fps,
            store: OnceLock::new(),
            recent: Mutex::new(BTreeMap::new()),
            stepped: Mutex::new(0),
        }
    }

    pub fn settings(&self) -> &RippleSettings {
        self.stepper.settings()
    }

    /// Reads and writes checkpoints in `store` from now on. A simulation has one store for its
    /// lifetime: a second call is ignored and returns false.
    pub fn set_store(&self, store: CheckpointStore) -> bool {
        self.store.set(store).is_ok()
    }

    pub fn store(&self) -> Option<&CheckpointStore> {
        self.store.get()
    }

    /// Frames stepped so far (each one an occupancy pair and a frame of substeps).
    pub fn frames_stepped(&self) -> u64 {
        *self.stepped.lock().unwrap()
    }

    /// The ripple state at `frame` (>= the first frame). `occupancy(f)` must return the
    /// characters' occupancy at frame `f` (see [`coupling::occupancy`]); it is called for the
    /// frames stepped through. Checkpoints of the frames stepped are written when a store is set.
    pub fn state_at(
        &self,
        frame: u32,
        occupancy: &dyn Fn(u32) -> Vec<f32>,
    ) -> Result<Arc<RippleState>, CheckpointError> {
        let frame = frame.max(self.first_frame);
        let settings = *self.settings();
        // The nearest earlier state: memory, then disk, then calm water at the first frame.
        let from_memory = {
            let recent = self.recent.lock().unwrap();
            recent
                .range(..=frame)
                .next_back()
                .map(|(&f, state)| (f, state.clone()))
        };
        let from_disk = |after: u32| {
            self.store.get().and_then(|store| {
                store
                    .latest_at_or_before(frame, self.first_frame, &settings)
                    .filter(|(f, _)| *f > after)
            })
        };
        let (mut at, mut state) = match from_memory {
            Some((f, state)) if f == frame => return Ok(state),
            Some((f, state)) => match from_disk(f) {
                Some((g, loaded)) => (g, loaded),
                None => (f, (*state).clone()),
            },
            None => match from_disk(self.first_frame.saturating_sub(1)) {
                Some((g, loaded)) if g >= self.first_frame => (g, loaded),
                _ => (self.first_frame, RippleState::calm(settings)),
            },
        };
        if at == self.first_frame {
            self.save(at, &state)?;
        }
        let mut occupancy_before = (at < frame).then(|| occupancy(at));
        while at < frame {
            let occupancy_now = occupancy(at + 1);
            let push = coupling::displacement(
                &settings,
                occupancy_before.as_deref().unwrap_or(&[]),
                &occupancy_now,
                self.strength,
            );
            self.stepper
                .advance_frame(&mut state, self.frame_secs, &push);
            at += 1;
            *self.stepped.lock().unwrap() += 1;
            self.save(at, &state)?;
            occupancy_before = Some(occupancy_now);
        }
        let state = Arc::new(state);
        let mut recent = self.recent.lock().unwrap();
        recent.insert(frame, state.clone());
        while recent.len() > STATES_KEPT {
            let oldest = *recent.keys().next().unwrap();
            recent.remove(&oldest);
        }
        Ok(state)
    }

    /// Which source `state_at(frame)` would start from (for reports and tests).
    pub fn source_for(&self, frame: u32) -> StateSource {
        if self.recent.lock().unwrap().contains_key(&frame) {
            return StateSource::Memory;
        }
        match self
            .store
            .get()
            .and_then(|store| store.latest_at_or_before(frame, self.first_frame, self.settings()))
        {
            Some((f, _)) => StateSource::Checkpoint(f),
            None => StateSource::Calm,
        }
    }

    /// Forgets the in-memory states (checkpoints on disk stay).
    pub fn forget_memory(&self) {
        self.recent.lock().unwrap().clear();
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
            nodes_x: 48,
            nodes_z: 32,
            min_x: -1.2,
            min_z: -0.8,
            spacing_m: 0.05,
            speed_m_per_s: 0.6,
            damping_per_s: 0.3,
            border: Border::Reflect,
            sponge_nodes: 0,
            sponge_damping_per_s: 0.0,
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
        let full = Simulation::new(settings(), 1.0, 1, 24.0);
        let straight: Vec<Arc<RippleState>> = (1..=30)
            .map(|f| full.state_at(f, &occupancy).unwrap())
            .collect();
        assert!(
            straight[29].max_abs_height_m() > 0.0,
            "the body made ripples"
        );

        // Alone, from calm water, jumping straight to frame 30.
        let alone = Simulation::new(settings(), 1.0, 1, 24.0);
        assert_eq!(*alone.state_at(30, &occupancy).unwrap(), *straight[29]);

        // Through checkpoints: a first run writes them, a second reads frame 20's and steps on.
        let dir = tempfile::tempdir().unwrap();
        let key = KeyHasher::new("test").input("scene", b"x").finish();
        let first = Simulation::new(settings(), 1.0, 1, 24.0);
        first.set_store(CheckpointStore::open(dir.path(), "s", key).unwrap());
        first.state_at(20, &occupancy).unwrap();
        let second = Simulation::new(settings(), 1.0, 1, 24.0);
        second.set_store(CheckpointStore::open(dir.path(), "s", key).unwrap());
        assert_eq!(second.source_for(26), StateSource::Checkpoint(20));
        assert_eq!(*second.state_at(26, &occupancy).unwrap(), *straight[25]);
        assert_eq!(
            second.frames_stepped(),
            6,
            "resumed from frame 20, not recomputed"
        );
        // An exact checkpoint hit steps nothing.
        let third = {
            let s = Simulation::new(settings(), 1.0, 1, 24.0);
            s.set_store(CheckpointStore::open(dir.path(), "s", key).unwrap());
            s
        };
        assert_eq!(*third.state_at(24, &occupancy).unwrap(), *straight[23]);
        assert_eq!(third.frames_stepped(), 0);
        // Backwards from memory: an earlier frame than the cached ones is recomputed correctly.
        assert_eq!(*full.state_at(3, &occupancy).unwrap(), *straight[2]);
    }
}
