//! What a frame is made from, hashed. Receives a scene and its loaded characters; returns the
//! BLAKE3 digest of every file they read (the scene file, each character's glTF with its buffers
//! and images, a glTF camera's file with its buffers, image textures), and from it the input hash written into each EXR header
//! (`snell.extra.inputHash`) that `snell render --resume` compares. The simulation checkpoint key
//! is made from the same digest, so the files are read and hashed once per job.

use std::path::{Path, PathBuf};

use super::characters::Character;
use super::SnellError;
use crate::scene::{Scene, SceneError};
use crate::sim::KeyHasher;

/// The digest of the scene file and every file it references, in a fixed order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneFilesDigest(pub [u8; 32]);

/// The hash of everything a rendered frame depends on besides the frame number: the scene's files,
/// the image size, the method and snell's version.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct InputHash(pub [u8; 32]);

impl InputHash {
    /// Lower-case hex, as written into EXR headers.
    pub fn hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// The EXR extra attribute (`snell.extra.<key>`) that holds a frame's [`InputHash`].
pub const INPUT_HASH_ATTRIBUTE: &str = "inputHash";

/// Every file `scene` and its `characters` read besides the scene file itself, sorted and without
/// repeats: characters' .gltf/.glb with their external buffers and images, a glTF camera's file
/// with its buffers, image textures.
pub fn referenced_files(scene: &Scene, characters: &[Character]) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = characters
        .iter()
        .flat_map(|c| c.asset.files().iter().cloned())
        .chain(scene.image_files())
        .chain(scene.camera.files().iter().cloned())
        .collect();
    files.sort();
    files.dedup();
    files
}

/// Reads and hashes the scene file and every [`referenced_files`] entry. Each file is labelled
/// with its path relative to the scene's folder, so the digest does not change when the project
/// is moved or the scene is named by an absolute path.
pub fn digest_scene_files(
    scene: &Scene,
    characters: &[Character],
) -> Result<SceneFilesDigest, SnellError> {
    // The scene and its assets passed these caps when they were loaded; a file swapped since then
    // for a FIFO or a device is refused here rather than blocking the hash.
    let read = |path: &Path, max_bytes: u64| {
        crate::files::read_regular(path, max_bytes)
            .map_err(|error| SnellError::Scene(SceneError::File(error)))
    };
    let scene_dir = scene.path.parent().unwrap_or(Path::new(""));
    let mut hasher = KeyHasher::new("snell-scene-files");
    hasher.input("scene", &read(&scene.path, crate::files::MAX_SCENE_BYTES)?);
    for file in referenced_files(scene, characters) {
        let label = file.strip_prefix(scene_dir).unwrap_or(&file);
        hasher.input(
            &label.to_string_lossy(),
            &read(&file, crate::files::MAX_ASSET_BYTES)?,
        );
    }
    Ok(SceneFilesDigest(hasher.finish().0))
}

/// The input hash of frames rendered from `files` at `width` x `height` with `method_label`.
pub fn input_hash(
    files: &SceneFilesDigest,
    width: u32,
    height: u32,
    method_label: &str,
) -> InputHash {
    let mut hasher = KeyHasher::new("snell-frame-inputs");
    hasher
        .input("scene-files", &files.0)
        .input("size", format!("{width}x{height}").as_bytes())
        .input("method", method_label.as_bytes())
        .input("version", crate::VERSION.as_bytes());
    InputHash(hasher.finish().0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn digest_of(scene_file: &Path) -> SceneFilesDigest {
        let scene = Scene::load(scene_file).unwrap();
        let mut textures = Vec::new();
        let characters = super::super::characters::load_characters(&scene, &mut textures).unwrap();
        digest_scene_files(&scene, &characters).unwrap()
    }

    /// Every input named by the design changes the hash: a byte of the scene, a byte of an image
    /// texture, the size, the method. Moving the whole project does not.
    #[test]
    fn the_hash_follows_every_input_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let image = dir.path().join("tile.png");
        image::RgbaImage::from_pixel(2, 2, image::Rgba([10, 20, 30, 255]))
            .save(&image)
            .unwrap();
        let scene_file = dir.path().join("scene.toml");
        let text = "[[object]]\nshape = \"sphere\"\nradius_m = 0.2\ntranslate = [0.0, -0.5, 0.0]\n\
                    texture = { image = \"tile.png\", size_m = [0.5, 0.5] }\n";
        std::fs::write(&scene_file, text).unwrap();
        let files = digest_of(&scene_file);
        assert_eq!(digest_of(&scene_file), files, "same inputs, same digest");
        let hash = input_hash(&files, 160, 90, "virtual-vertices/equal-t");
        assert_eq!(
            input_hash(&files, 160, 90, "virtual-vertices/equal-t"),
            hash
        );
        assert_ne!(
            input_hash(&files, 160, 91, "virtual-vertices/equal-t"),
            hash
        );
        assert_ne!(
            input_hash(&files, 90, 160, "virtual-vertices/equal-t"),
            hash
        );
        assert_ne!(input_hash(&files, 160, 90, "raytrace"), hash);
        assert_eq!(hash.hex().len(), 64);

        // The same project in another folder: the same digest.
        let moved = tempfile::tempdir().unwrap();
        std::fs::copy(&image, moved.path().join("tile.png")).unwrap();
        std::fs::copy(&scene_file, moved.path().join("scene.toml")).unwrap();
        assert_eq!(digest_of(&moved.path().join("scene.toml")), files);

        image::RgbaImage::from_pixel(2, 2, image::Rgba([10, 20, 31, 255]))
            .save(&image)
            .unwrap();
        let edited_image = digest_of(&scene_file);
        assert_ne!(edited_image, files, "a texture pixel changed");

        std::fs::write(&scene_file, text.replace("0.2", "0.25")).unwrap();
        assert_ne!(digest_of(&scene_file), edited_image, "the scene changed");
    }
}
