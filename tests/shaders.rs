//! Every WGSL module the renderer creates, assembled exactly as it assembles them, parsed and
//! validated by naga; all failures are collected (file:line:column of the piece they come from)
//! before the test fails.

use std::collections::BTreeSet;
use std::path::Path;

use snell::gpu::shaders::{assembled_shaders, ShaderModuleSource};

fn describe(
    module: &ShaderModuleSource,
    line: Option<u32>,
    column: Option<u32>,
    message: &str,
) -> String {
    let place = match line {
        Some(line) => {
            let (file, line_in_file) = module.origin_of_line(line as usize);
            format!("{file}:{line_in_file}:{}", column.unwrap_or(0))
        }
        None => module.file.to_string(),
    };
    format!("{place} (module \"{}\"): {message}", module.name)
}

fn check_module(module: &ShaderModuleSource) -> Result<(), String> {
    let parsed = naga::front::wgsl::parse_str(&module.source).map_err(|error| {
        let location = error.location(&module.source);
        describe(
            module,
            location.map(|l| l.line_number),
            location.map(|l| l.line_position),
            &error.emit_to_string(&module.source),
        )
    })?;
    let mut validator = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    );
    validator.validate(&parsed).map_err(|error| {
        let location = error.location(&module.source);
        describe(
            module,
            location.map(|l| l.line_number),
            location.map(|l| l.line_position),
            &error.emit_to_string(&module.source),
        )
    })?;
    Ok(())
}

#[test]
fn every_shader_module_parses_and_validates() {
    let modules = assembled_shaders();
    // The renderer's passes: sky, above, membrane, water_clear, under.
    assert!(
        modules.len() >= 5,
        "found only {} shader modules",
        modules.len()
    );

    // Every pass file in shaders/ must be part of some module, or it is never checked (nor used).
    let shader_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let on_disk: BTreeSet<String> = std::fs::read_dir(&shader_dir)
        .unwrap_or_else(|error| panic!("cannot list {}: {error}", shader_dir.display()))
        .filter_map(|entry| entry.ok())
        .map(|entry| entry.file_name().to_string_lossy().into_owned())
        .filter(|name| name.ends_with(".wgsl") && !name.ends_with(".inc.wgsl"))
        .map(|name| format!("shaders/{name}"))
        .collect();
    let assembled: BTreeSet<String> = modules
        .iter()
        .map(|module| module.file.to_string())
        .collect();
    assert!(
        !on_disk.is_empty(),
        "no shaders found in {}",
        shader_dir.display()
    );
    assert_eq!(
        on_disk, assembled,
        "shader files on disk and modules the renderer assembles differ"
    );

    let failures: Vec<String> = modules
        .iter()
        .filter_map(|module| check_module(module).err())
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} shader modules failed:\n\n{}",
        failures.len(),
        modules.len(),
        failures.join("\n\n")
    );
}

#[test]
fn a_broken_shader_is_reported_against_its_own_file() {
    // The checker itself must be able to fail and point at the right file and line.
    let mut module = assembled_shaders()
        .into_iter()
        .next()
        .expect("at least one module");
    module
        .source
        .push_str("\nfn broken() -> f32 { return undefined_name; }\n");
    let failure = check_module(&module).expect_err("an undefined name must fail validation");
    let expected_line = module.source.lines().count() - module.prelude_lines;
    assert!(
        failure.starts_with(&format!("{}:{expected_line}:", module.file)),
        "{failure}"
    );
}
