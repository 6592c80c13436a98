//! Stage 0, scene: the TOML scene file (serde, `deny_unknown_fields`, defaults), validated into a
//! [`Scene`] with errors that name file, line, column and key; built-in primitives (box, sphere,
//! quad, tiled pool) turned into world-space meshes; procedural and image textures.
//! OWNER: scene helper.
