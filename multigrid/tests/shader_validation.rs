//! Every `shaders/*.wgsl` parses and validates with naga (no GPU needed), after `#import` resolution
//! (with its slots' default files, and as every kernel that uses it), and every file on disk is a
//! kernel's file the solver knows (and the other way round).

use std::path::PathBuf;

use terrasketch_multigrid::gpu::shaders::{Kernel, SHARED, SLOTS, preprocess};

fn shader_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shaders")
}

fn validate(name: &str, source: &str) -> Result<naga::valid::ModuleInfo, String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| format!("{name}: {}", e.emit_to_string(source)))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .map_err(|e| format!("{name}: {}", e.emit_to_string(source)))
}

#[test]
fn every_wgsl_file_validates() {
    let mut failures = Vec::new();
    let mut count = 0;
    for entry in std::fs::read_dir(shader_dir()).expect("shaders/ exists") {
        let path = entry.expect("dir entry").path();
        if path.extension().and_then(|e| e.to_str()) != Some("wgsl") {
            continue;
        }
        count += 1;
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let raw = std::fs::read_to_string(&path).expect("readable");
        match preprocess(&raw) {
            Ok(src) => {
                if let Err(e) = validate(&name, &src) {
                    failures.push(e);
                }
            }
            Err(e) => failures.push(format!("{name}: {e}")),
        }
    }
    let mut files: Vec<&str> = Kernel::ALL.iter().map(|k| k.file()).collect();
    files.sort();
    files.dedup();
    assert_eq!(count, files.len(), "one .wgsl file per kernel file");
    // Each kernel as it is built: its file with the slot files it chooses.
    for k in Kernel::ALL {
        if let Err(e) = validate(&k.name(), &k.source()) {
            failures.push(e);
        }
    }
    assert!(
        failures.is_empty(),
        "invalid shaders:\n{}",
        failures.join("\n\n")
    );
}

#[test]
fn files_on_disk_are_the_embedded_kernels() {
    for k in Kernel::ALL {
        let path = shader_dir().join(format!("{}.wgsl", k.file()));
        let disk =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(
            disk,
            k.raw_source(),
            "{} differs from the embedded copy (rebuild)",
            k.name()
        );
        assert!(
            k.raw_source().starts_with("// Pass: "),
            "{}: header comment missing",
            k.name()
        );
        assert!(
            k.raw_source().contains("Workgroup"),
            "{}: header must state the workgroup size",
            k.name()
        );
    }
    for entry in std::fs::read_dir(shader_dir().join("shared")).expect("shaders/shared exists") {
        let path = entry.expect("dir entry").path();
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        assert!(
            SHARED.iter().any(|(n, _)| *n == stem),
            "shared/{stem}.wgsl is not importable"
        );
    }
    for (slot, default) in SLOTS {
        assert!(SHARED.iter().any(|(n, _)| *n == default), "slot {slot}");
        assert!(
            !SHARED.iter().any(|(n, _)| *n == slot),
            "slot {slot} shadows a file"
        );
    }
    for k in Kernel::ALL {
        for (slot, file) in k.imports() {
            assert!(SLOTS.iter().any(|(s, _)| s == slot), "{}: {slot}", k.name());
            assert!(
                SHARED.iter().any(|(n, _)| n == file),
                "{}: {file}",
                k.name()
            );
        }
    }
}

#[test]
fn every_kernel_has_entry_point_main_and_declares_its_bindings() {
    for k in Kernel::ALL {
        let src = k.source();
        let module = naga::front::wgsl::parse_str(&src).expect("parses");
        assert!(
            module.entry_points.iter().any(|e| e.name == "main"),
            "{}: no `main`",
            k.name()
        );
        let mut bindings: Vec<u32> = module
            .global_variables
            .iter()
            .filter_map(|(_, g)| g.binding.as_ref().map(|b| b.binding))
            .collect();
        bindings.sort();
        let expected: Vec<u32> = (0..=k.bindings().len() as u32).collect();
        assert_eq!(
            bindings,
            expected,
            "{}: bindings do not match Kernel::bindings",
            k.name()
        );
    }
}
