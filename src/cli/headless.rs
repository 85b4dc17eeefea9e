//! The environment of the headless commands: no GPU is started unless asked for, and the GPU
//! is probed without touching an absent display server.
//!
//! burn materialises a loaded optimiser state on its *default* device, which is the GPU when
//! burn-wgpu is compiled in: resuming a CPU run started a GPU (seconds of start-up, and the
//! display errors below) just to read a checkpoint. The headless commands make burn's CPU
//! backend the default (`BURN_DEVICE=flex`); every tensor of a GPU run is created on its device
//! explicitly, and the optimiser moves its state to the parameters' device at the next step.
//!
//! Mesa's Vulkan device-selection layer, an implicit layer loaded by every Vulkan instance,
//! connects to the Wayland display to find the GPU that drives it. Without a valid
//! `XDG_RUNTIME_DIR` libwayland then prints "error: XDG_RUNTIME_DIR is invalid or not set in
//! the environment." at every adapter enumeration (burn's wgpu device, the offscreen
//! renderer), although no window is opened. The headless commands need no display, so they
//! turn that layer off through its documented switch `NODEVICE_SELECT=1` when the session has
//! no runtime folder. A value the user set is kept.

use std::ffi::OsStr;
use std::path::Path;

/// The layer's switch.
pub const SWITCH: &str = "NODEVICE_SELECT";
/// burn's choice of default device.
pub const BURN_DEVICE: &str = "BURN_DEVICE";

/// Whether the device-selection layer must be turned off, given the current values of
/// `NODEVICE_SELECT` and `XDG_RUNTIME_DIR`.
pub fn needs_quiet_probe(switch: Option<&OsStr>, runtime_dir: Option<&OsStr>) -> bool {
    let runtime_ok = runtime_dir.is_some_and(|d| {
        let d = Path::new(d);
        d.is_absolute() && d.is_dir()
    });
    switch.is_none() && !runtime_ok
}

/// Makes the CPU backend burn's default device (unless the user chose one) and turns the
/// device-selection layer off when there is no desktop session. Must be called before any
/// other thread starts (it changes the environment).
pub fn headless_environment() {
    let switch = std::env::var_os(SWITCH);
    let runtime_dir = std::env::var_os("XDG_RUNTIME_DIR");
    if needs_quiet_probe(switch.as_deref(), runtime_dir.as_deref()) {
        // SAFETY: called from `main` before any thread is spawned, so no other thread reads
        // or writes the environment concurrently.
        unsafe { std::env::set_var(SWITCH, "1") };
    }
    if std::env::var_os(BURN_DEVICE).is_none() {
        // SAFETY: as above.
        unsafe { std::env::set_var(BURN_DEVICE, "flex") };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layer_is_turned_off_only_without_a_runtime_folder_and_a_user_choice() {
        let tmp = std::env::temp_dir();
        let dir = Some(tmp.as_os_str());
        assert!(needs_quiet_probe(None, None));
        assert!(needs_quiet_probe(None, Some(OsStr::new("relative/dir"))));
        assert!(needs_quiet_probe(None, Some(OsStr::new("/no/such/folder"))));
        assert!(!needs_quiet_probe(None, dir));
        assert!(!needs_quiet_probe(Some(OsStr::new("0")), None));
    }
}
