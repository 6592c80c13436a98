//! Simulation checkpoints on disk: the ripple state after each frame, in a folder named for the
//! scene and a key (a BLAKE3 hash of the scene file, every asset it references and every setting
//! that changes the simulation), next to the rendered frames.
//!
//! A checkpoint is used only when its folder's key, its own header key, frame and grid size all
//! match and its trailing hash checks, so a stale one (the scene or an asset changed) or a torn one
//! is never read. Files are written to a temporary name and renamed, so a crash leaves whole
//! checkpoints or none, and processes rendering one version of a scene share its folder.
//!
//! Several versions of a scene may be rendered into one folder at once (an edited scene beside
//! the original, on a farm): each store holds a shared lock on its folder's `.lock` file while it
//! is open. When a store opens, the [`KEPT_VERSIONS`] most recently opened versions of the scene
//! are kept; an older one is removed only when no process holds its lock.

use std::fs;
use std::io::Write;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use super::ripples::{RippleSettings, RippleState};

const MAGIC: &[u8; 8] = b"SNELLRIP";
/// Bumped whenever the file layout changes.
const FORMAT_VERSION: u32 = 1;
/// The folder, under the output folder, that holds every scene's checkpoints.
pub const CHECKPOINT_DIR: &str = ".snell-sim";
/// How many versions of one scene keep their checkpoints (the most recently opened ones).
pub const KEPT_VERSIONS: usize = 4;
/// In each version's folder: locked (shared) by every process using it; its modification time
/// says when the version was last opened.
const LOCK_FILE: &str = ".lock";

/// The inputs a simulation depends on, hashed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CheckpointKey(pub [u8; 32]);

impl CheckpointKey {
    pub fn hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// Builds a [`CheckpointKey`]: feed it every input, in a fixed order.
pub struct KeyHasher(blake3::Hasher);

impl KeyHasher {
    pub fn new(what: &str) -> Self {
        let mut hasher = blake3::Hasher::new();
        hasher.update(what.as_bytes());
        hasher.update(&FORMAT_VERSION.to_le_bytes());
        KeyHasher(hasher)
    }
    /// A labelled input: the label and length go in first so inputs cannot run into each other.
    pub fn input(&mut self, label: &str, bytes: &[u8]) -> &mut Self {
        self.0.update(&(label.len() as u64).to_le_bytes());
        self.0.update(label.as_bytes());
        self.0.update(&(bytes.len() as u64).to_le_bytes());
        self.0.update(bytes);
        self
    }
    pub fn finish(&self) -> CheckpointKey {
        CheckpointKey(*self.0.finalize().as_bytes())
    }
}

/// Why checkpoints could not be used or written.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error("cannot create the simulation checkpoint folder {path}: {source}")]
    CreateDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write the simulation checkpoint {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl CheckpointError {
    /// Whether the output location is at fault (a folder that cannot be made: exit 2) rather
    /// than a write failing mid-render (a full disk: exit 1).
    pub fn is_bad_input(&self) -> bool {
        matches!(self, CheckpointError::CreateDir { .. })
    }
}

/// One scene's checkpoint folder.
#[derive(Debug)]
pub struct CheckpointStore {
    dir: PathBuf,
    key: CheckpointKey,
    /// Folders of older versions of the same scene removed when the store opened.
    pub removed_stale: Vec<PathBuf>,
    /// Held (shared) while the store is open, so no other process removes the folder.
    _lock: fs::File,
}

/// Opens `dir/.lock` (creating `dir`) and holds a shared lock on it, marking the version as just
/// used. Retries when the folder was removed while this process waited for the lock.
fn lock_folder(dir: &Path) -> Result<fs::File, CheckpointError> {
    let create_error = |source| CheckpointError::CreateDir {
        path: dir.to_path_buf(),
        source,
    };
    loop {
        fs::create_dir_all(dir).map_err(create_error)?;
        let path = dir.join(LOCK_FILE);
        let file = fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(create_error)?;
        crate::output::lock::lock(&file, crate::output::lock::Lock::Shared)
            .map_err(create_error)?;
        // A remover holds the lock exclusively while it moves the folder away: if it did, this
        // lock is on a file no longer at `path`. Then start again with a new folder.
        if same_file(&file, &path) {
            let _ = file.set_modified(std::time::SystemTime::now());
            return Ok(file);
        }
    }
}

#[cfg(unix)]
fn same_file(file: &fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), fs::metadata(path)) {
        (Ok(held), Ok(there)) => held.dev() == there.dev() && held.ino() == there.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &fs::File, path: &Path) -> bool {
    path.is_file()
}

/// Removes the version folder `dir` if no process holds its lock: locks it exclusively (without
/// waiting), moves it to a hidden name and deletes that. Whether it was removed.
fn remove_unused_version(root: &Path, dir: &Path) -> bool {
    let Ok(file) = fs::OpenOptions::new().write(true).open(dir.join(LOCK_FILE)) else {
        // A folder without a lock file is from a version before locks; nobody can hold it.
        return remove_moved(root, dir);
    };
    if crate::output::lock::lock(&file, crate::output::lock::Lock::TryExclusive).is_err() {
        return false; // in use
    }
    remove_moved(root, dir)
}

fn remove_moved(root: &Path, dir: &Path) -> bool {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let trash = crate::output::temporary::temporary_path_for(&root.join(name));
    if fs::rename(dir, &trash).is_err() {
        return false;
    }
    fs::remove_dir_all(&trash).is_ok()
}

impl CheckpointStore {
    /// Opens (creating) `<out_dir>/.snell-sim/<scene_stem>-<key>/` and holds its lock. Of the
    /// other folders of the same scene stem (other versions of the scene or its assets), keeps
    /// the [`KEPT_VERSIONS`] - 1 most recently opened and those another process has open, and
    /// removes the rest.
    pub fn open(
        out_dir: &Path,
        scene_stem: &str,
        key: CheckpointKey,
    ) -> Result<Self, CheckpointError> {
        let root = out_dir.join(CHECKPOINT_DIR);
        let name = format!("{scene_stem}-{}", &key.hex()[..32]);
        let dir = root.join(&name);
        let lock = lock_folder(&dir)?;
        let mut others: Vec<(std::time::SystemTime, PathBuf)> = fs::read_dir(&root)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|entry| {
                let other = entry.file_name().to_string_lossy().to_string();
                let same_scene = other
                    .rsplit_once('-')
                    .is_some_and(|(stem, hash)| stem == scene_stem && hash.len() == 32);
                same_scene && other != name && entry.path().is_dir()
            })
            .map(|entry| {
                let used = fs::metadata(entry.path().join(LOCK_FILE))
                    .or_else(|_| entry.metadata())
                    .and_then(|meta| meta.modified())
                    .unwrap_or(std::time::UNIX_EPOCH);
                (used, entry.path())
            })
            .collect();
        // Most recently used first; the oldest beyond the kept ones go, unless in use.
        others.sort_by(|a, b| b.cmp(a));
        let removed_stale = others
            .into_iter()
            .skip(KEPT_VERSIONS - 1)
            .filter(|(_, path)| remove_unused_version(&root, path))
            .map(|(_, path)| path)
            .collect();
        Ok(CheckpointStore {
            dir,
            key,
            removed_stale,
            _lock: lock,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn path_of(&self, frame: u32) -> PathBuf {
        self.dir.join(format!("ripples-{frame:06}.bin"))
    }

    /// The latest frame in `frames` with a valid checkpoint, and its state. Only checkpoints in
    /// the range are read.
    pub fn latest_in(
        &self,
        frames: RangeInclusive<u32>,
        settings: &RippleSettings,
    ) -> Option<(u32, RippleState)> {
        let mut frames: Vec<u32> = fs::read_dir(&self.dir)
            .ok()?
            .flatten()
            .filter_map(|entry| {
                let name = entry.file_name().to_string_lossy().to_string();
                name.strip_prefix("ripples-")?
                    .strip_suffix(".bin")?
                    .parse::<u32>()
                    .ok()
            })
            .filter(|f| frames.contains(f))
            .collect();
        frames.sort_unstable_by(|a, b| b.cmp(a));
        frames
            .into_iter()
            .find_map(|f| self.load(f, settings).map(|state| (f, state)))
    }

    /// The checkpoint of `frame`, if present and valid for this key and grid.
    pub fn load(&self, frame: u32, settings: &RippleSettings) -> Option<RippleState> {
        let bytes = fs::read(self.path_of(frame)).ok()?;
        decode(&bytes, self.key, frame, settings)
    }

    pub fn has(&self, frame: u32) -> bool {
        self.path_of(frame).is_file()
    }

    /// Writes the checkpoint of `frame` atomically (temporary file, then rename).
    pub fn save(&self, frame: u32, state: &RippleState) -> Result<(), CheckpointError> {
        let path = self.path_of(frame);
        // Named and registered like every output's temporary file, so an immediate stop removes
        // it and the next render removes it when a killed process left it.
        let temporary = crate::output::temporary::temporary_path_for(&path);
        let bytes = encode(self.key, frame, state);
        let write = || -> std::io::Result<()> {
            let mut file = crate::output::temporary::create(&temporary)?;
            file.write_all(&bytes)?;
            file.sync_data()?;
            fs::rename(&temporary, &path)
        };
        let result = write().map_err(|source| {
            let _ = fs::remove_file(&temporary);
            CheckpointError::Write { path, source }
        });
        crate::output::temporary::release(&temporary);
        result
    }
}

fn encode(key: CheckpointKey, frame: u32, state: &RippleState) -> Vec<u8> {
    let s = &state.settings;
    let mut bytes = Vec::with_capacity(64 + 8 * state.height_m.len() + 32);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&key.0);
    bytes.extend_from_slice(&frame.to_le_bytes());
    bytes.extend_from_slice(&s.nodes_x.to_le_bytes());
    bytes.extend_from_slice(&s.nodes_z.to_le_bytes());
    for value in state.height_m.iter().chain(&state.velocity_m_per_s) {
        bytes.extend_from_slice(&value.to_le_bytes());
    }
    let check = blake3::hash(&bytes);
    bytes.extend_from_slice(check.as_bytes());
    bytes
}

fn decode(
    bytes: &[u8],
    key: CheckpointKey,
    frame: u32,
    settings: &RippleSettings,
) -> Option<RippleState> {
    let nodes = settings.node_count();
    let header = 8 + 4 + 32 + 4 + 4 + 4;
    if bytes.len() != header + 8 * nodes + 32 {
        return None;
    }
    let (body, check) = bytes.split_at(bytes.len() - 32);
    if blake3::hash(body).as_bytes() != check {
        return None;
    }
    let u32_at = |at: usize| u32::from_le_bytes(body[at..at + 4].try_into().unwrap());
    if &body[..8] != MAGIC
        || u32_at(8) != FORMAT_VERSION
        || body[12..44] != key.0
        || u32_at(44) != frame
        || u32_at(48) != settings.nodes_x
        || u32_at(52) != settings.nodes_z
    {
        return None;
    }
    let values: Vec<f32> = body[header..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let (height_m, velocity_m_per_s) = values.split_at(nodes);
    Some(RippleState {
        settings: *settings,
        height_m: height_m.to_vec(),
        velocity_m_per_s: velocity_m_per_s.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> RippleSettings {
        RippleSettings {
            min_x: 0.0,
            min_z: 0.0,
            damping_per_s: 0.1,
            ..crate::sim::spectral::tests::settings(5, 3, 0.1)
        }
    }

    fn key(text: &str) -> CheckpointKey {
        KeyHasher::new("test")
            .input("scene", text.as_bytes())
            .finish()
    }

    #[test]
    fn round_trip_and_every_mismatch_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let store = CheckpointStore::open(dir.path(), "pool", key("a")).unwrap();
        let mut state = RippleState::calm(settings());
        state.height_m[3] = 0.25;
        state.velocity_m_per_s[7] = -1.5e-3;
        store.save(12, &state).unwrap();
        assert_eq!(store.load(12, &settings()), Some(state.clone()));
        assert_eq!(
            store.latest_in(1..=20, &settings()).map(|(f, _)| f),
            Some(12)
        );
        assert_eq!(store.latest_in(1..=11, &settings()), None);
        // Another grid size: refused.
        let mut other = settings();
        other.nodes_x = 4;
        assert_eq!(store.load(12, &other), None);
        // A torn (truncated) or corrupted file: refused.
        let path = store.path_of(12);
        let bytes = fs::read(&path).unwrap();
        fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
        assert_eq!(store.load(12, &settings()), None);
        let mut flipped = bytes.clone();
        flipped[70] ^= 1;
        fs::write(&path, &flipped).unwrap();
        assert_eq!(store.load(12, &settings()), None);
        // A file renamed to another frame: refused (the frame is in the header).
        fs::write(&path, &bytes).unwrap();
        fs::copy(&path, store.path_of(13)).unwrap();
        assert_eq!(store.load(13, &settings()), None);
        assert!(store.load(12, &settings()).is_some());
    }

    /// Versions of a scene open at once keep their folders; once closed, only the most
    /// recently opened ones are kept, and other scenes' folders are never touched.
    #[test]
    fn versions_in_use_are_kept_and_only_the_oldest_unused_go() {
        let dir = tempfile::tempdir().unwrap();
        let calm = RippleState::calm(settings());
        let other_scene = CheckpointStore::open(dir.path(), "fox", key("a")).unwrap();
        other_scene.save(5, &calm).unwrap();
        let other_scene_dir = other_scene.dir().to_path_buf();
        drop(other_scene);
        // The first version stays open (another process rendering it) through all the others.
        let held = CheckpointStore::open(dir.path(), "pool", key("held")).unwrap();
        held.save(5, &calm).unwrap();
        let mut closed = Vec::new();
        for version in ["v1", "v2", "v3", "v4", "v5"] {
            let store = CheckpointStore::open(dir.path(), "pool", key(version)).unwrap();
            store.save(5, &calm).unwrap();
            closed.push(store.dir().to_path_buf());
            // Opened in this order: modification times must differ.
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert!(held.dir().exists(), "a version in use is never removed");
        assert_eq!(held.latest_in(1..=10, &settings()).map(|(f, _)| f), Some(5));
        assert!(
            other_scene_dir.exists(),
            "other scenes' checkpoints are kept"
        );
        // v5 was opened last: v2-v4 are its KEPT_VERSIONS - 1 most recent others besides the held
        // one; v1 went when v5 opened (v1 closed, older than the three before it).
        let present: Vec<bool> = closed.iter().map(|path| path.exists()).collect();
        assert_eq!(present, [false, true, true, true, true]);
        // Nothing half-removed is left behind.
        let names: Vec<String> = fs::read_dir(dir.path().join(CHECKPOINT_DIR))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !n.contains(".tmp-")), "{names:?}");
    }
}
