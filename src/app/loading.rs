//! Loading scene parts from files: the one code path used by the file dialogs, the typed-path
//! fields and project files. Every failure is an error message naming the file (shown in the
//! UI), never a panic.

use std::path::Path;
use std::sync::Arc;

use crate::io::{ImportOptions, RetargetOptions};
use crate::scene::{Avatar, Garment, GarmentOptions, Motion};

/// What a loader produced, with its non-fatal warnings.
#[derive(Clone, Debug)]
pub struct Loaded<T> {
    /// The loaded value.
    pub value: T,
    /// Non-fatal problems noticed while loading (shown in the UI).
    pub warnings: Vec<String>,
}

/// Lower-case extension of `path` ("" when it has none).
pub fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Loads a skinned avatar (glTF/GLB) with its animations resampled to `fps`.
pub fn load_avatar(path: &Path, fps: f32) -> Result<Loaded<Arc<Avatar>>, String> {
    match extension(path).as_str() {
        "glb" | "gltf" => {}
        other => {
            return Err(format!(
                "unsupported avatar file type '{other}' (expected glb or gltf): {}",
                path.display()
            ));
        }
    }
    let options = ImportOptions {
        fps,
        ..Default::default()
    };
    let loaded = crate::io::load_avatar(path, &options).map_err(|e| e.to_string())?;
    Ok(Loaded {
        value: Arc::new(loaded.avatar),
        warnings: loaded.warnings,
    })
}

/// Loads a garment template (OBJ or glTF/GLB, already in the avatar's rest pose) and binds it
/// to `avatar` (skin-weight transfer; more smoothing for skirts and dresses by name).
pub fn load_garment(path: &Path, avatar: &Avatar) -> Result<Loaded<Arc<Garment>>, String> {
    let options = ImportOptions::default();
    let loaded = match extension(path).as_str() {
        "obj" => crate::io::load_obj(path, &options),
        "glb" | "gltf" => crate::io::load_gltf_mesh(path, &options),
        other => {
            return Err(format!(
                "unsupported garment file type '{other}' (expected obj, glb or gltf): {}",
                path.display()
            ));
        }
    }
    .map_err(|e| e.to_string())?;
    // The passes chosen here are kept in `Garment::smoothing_passes`, which the run's scene
    // description records.
    let garment_options = GarmentOptions::for_name(&loaded.name);
    let garment = Garment::new(loaded.name.clone(), loaded.mesh, avatar, &garment_options)
        .map_err(|e| format!("{e}: {}", path.display()))?;
    let mut warnings = loaded.warnings;
    warnings.extend(garment.warnings.iter().cloned());
    Ok(Loaded {
        value: Arc::new(garment),
        warnings,
    })
}

/// Loads a BVH motion and retargets it onto `avatar`'s skeleton at `fps`.
pub fn load_motion(path: &Path, avatar: &Avatar, fps: f32) -> Result<Loaded<Motion>, String> {
    if extension(path) != "bvh" {
        return Err(format!(
            "unsupported motion file type '{}' (expected bvh): {}",
            extension(path),
            path.display()
        ));
    }
    let bvh = crate::io::load_bvh(path).map_err(|e| e.to_string())?;
    let options = RetargetOptions {
        fps,
        ..Default::default()
    };
    let (motion, warnings) =
        crate::io::retarget_bvh(&bvh, &avatar.skeleton, &options).map_err(|e| e.to_string())?;
    Ok(Loaded {
        value: motion,
        warnings,
    })
}
