//! `neural-cloth fit --avatar A --garment G`: puts a garment made for another body, in other
//! units, with another origin or mirrored onto the avatar's rest pose, relaxes it there with
//! the simulator and writes it as an OBJ to train on; prints what it did.

use std::path::{Path, PathBuf};

use anyhow::Context;

use neural_cloth::fit::{FitOptions, Fitted, MirrorMode, RelaxSettings, fit_file, write_obj};
use neural_cloth::geometry::Vec3;
use neural_cloth::io::{ImportOptions, Units, UpAxis, load_avatar};
use neural_cloth::scene::Avatar;

/// Arguments of `fit`.
#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Skinned avatar (glTF/GLB), or `mannequin` for the built-in one.
    #[arg(long)]
    pub avatar: PathBuf,
    /// Garment file (OBJ, glTF or GLB) to fit.
    #[arg(long)]
    pub garment: PathBuf,
    /// Output OBJ, in metres (default: GARMENT-fitted.obj beside the garment).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Unit of the garment file: m, dm, cm, mm or in (default: chosen from its size against
    /// the avatar's height).
    #[arg(long, value_parser = parse_units)]
    pub units: Option<Units>,
    /// Up axis of the garment file: auto (detected from its shape), y or z.
    #[arg(long, default_value = "auto")]
    pub up: UpAxis,
    /// Uniform scale of the garment about its centre, after the unit conversion (default:
    /// estimated within --scale-range).
    #[arg(long)]
    pub scale: Option<f32>,
    /// Range LO,HI of the estimated scale (default 0.7,1.45).
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true)]
    pub scale_range: Option<(f32, f32)>,
    /// Translation x,y,z of the garment's centre in metres (default: estimated).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub offset: Option<Vec3>,
    /// Left/right mirroring: auto (when the faces turn towards the body), flip or keep.
    #[arg(long, value_parser = parse_mirror, default_value = "auto")]
    pub mirror: MirrorMode,
    /// Do not relax the aligned garment with the simulator.
    #[arg(long)]
    pub no_relax: bool,
    /// Do not carry a garment made for other arms (a T-pose shirt on an A-pose avatar) or
    /// another stance (trousers made with the feet apart) back to the avatar's rest pose.
    #[arg(long)]
    pub no_repose: bool,
    /// Seconds the simulator lets the garment settle on the rest pose (default 1).
    #[arg(long, conflicts_with = "no_relax")]
    pub relax_secs: Option<f32>,
}

/// Parses a unit name.
fn parse_units(s: &str) -> Result<Units, String> {
    match s.to_ascii_lowercase().as_str() {
        "m" | "metres" | "meters" => Ok(Units::Metres),
        "dm" | "decimetres" | "decimeters" => Ok(Units::Decimetres),
        "cm" | "centimetres" | "centimeters" => Ok(Units::Centimetres),
        "mm" | "millimetres" | "millimeters" => Ok(Units::Millimetres),
        "in" | "inches" => Ok(Units::Inches),
        other => Err(format!("unknown unit '{other}' (m, dm, cm, mm or in)")),
    }
}

/// Parses `a,b,...` as `N` finite numbers.
fn parse_numbers<const N: usize>(s: &str) -> Result<[f32; N], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(format!("'{s}': expected {N} comma-separated numbers"));
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(parts) {
        *o = p
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{p}' is not a finite number"))?;
    }
    Ok(out)
}

/// Parses `lo,hi`.
fn parse_pair(s: &str) -> Result<(f32, f32), String> {
    parse_numbers::<2>(s).map(|[a, b]| (a, b))
}

/// Parses `x,y,z`.
fn parse_vec3(s: &str) -> Result<Vec3, String> {
    parse_numbers::<3>(s).map(Vec3::from)
}

/// Parses a mirror mode.
fn parse_mirror(s: &str) -> Result<MirrorMode, String> {
    match s {
        "auto" => Ok(MirrorMode::Auto),
        "flip" => Ok(MirrorMode::Flip),
        "keep" => Ok(MirrorMode::Keep),
        other => Err(format!(
            "unknown mirror mode '{other}' (auto, flip or keep)"
        )),
    }
}

/// The avatar at `path`, or the built-in mannequin for `mannequin`.
pub fn load_avatar_arg(path: &Path) -> anyhow::Result<Avatar> {
    if path == Path::new("mannequin") && !path.exists() {
        return Ok(neural_cloth::scene::procedural::mannequin()?);
    }
    let loaded = load_avatar(path, &ImportOptions::default())?;
    for w in &loaded.warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(loaded.avatar)
}

/// The default output path: `GARMENT-fitted.obj` beside the garment.
fn default_out(garment: &Path) -> PathBuf {
    let stem = garment
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "garment".into());
    garment.with_file_name(format!("{stem}-fitted.obj"))
}

/// The fit options the arguments give.
fn options(args: &FitArgs) -> FitOptions {
    let defaults = FitOptions::default();
    let relax = if args.no_relax {
        None
    } else {
        Some(RelaxSettings {
            settle_secs: args
                .relax_secs
                .unwrap_or(RelaxSettings::default().settle_secs),
            ..RelaxSettings::default()
        })
    };
    FitOptions {
        units: args.units.unwrap_or(Units::Auto),
        up: args.up,
        scale: args.scale,
        scale_range: args.scale_range.unwrap_or(defaults.scale_range),
        offset_m: args.offset,
        mirror: args.mirror,
        relax,
        repose: !args.no_repose,
        ..defaults
    }
}

/// Runs `fit`.
pub fn run(args: FitArgs) -> anyhow::Result<()> {
    let avatar = load_avatar_arg(&args.avatar)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| default_out(&args.garment));
    let fitted = fit_file(&avatar, &args.garment, &options(&args))?;
    write_obj(&fitted, &out).with_context(|| format!("writing {}", out.display()))?;
    print!("{}", summary(&fitted, &avatar, &args));
    println!("wrote {}", out.display());
    println!(
        "train on it: neural-cloth train --avatar {} --garment {} --motions DIR",
        args.avatar.display(),
        out.display()
    );
    Ok(())
}

/// What the fit did, in lines.
fn summary(fitted: &Fitted, avatar: &Avatar, args: &FitArgs) -> String {
    let r = &fitted.report;
    let p = &r.placement;
    let how_units = if r.units_detected {
        "chosen from its size against the avatar's height"
    } else {
        "as given"
    };
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    let relaxed = r
        .inside_relaxed
        .map_or_else(|| "not relaxed".to_string(), |n| format!("{n} relaxed"));
    let limb = |degrees: f32, made: String, matches: &str| {
        if degrees == 0.0 {
            matches.to_string()
        } else if r.reposed {
            format!("{made}; re-posed to its rest pose")
        } else {
            format!("{made}; not re-posed (--no-repose)")
        }
    };
    let sleeves = limb(
        r.sleeves_deg,
        format!(
            "made {:.0} degrees {} the avatar's arms",
            r.sleeves_deg.abs(),
            if r.sleeves_deg > 0.0 {
                "above"
            } else {
                "below"
            }
        ),
        "match the avatar's arms",
    );
    let legs = match r.legs_deg {
        None => String::new(),
        Some(d) => {
            let made = format!(
                "made {:.0} degrees {} than the avatar's",
                d.abs(),
                if d > 0.0 {
                    "wider apart"
                } else {
                    "closer together"
                }
            );
            format!(
                "\x20 legs:    {}\n",
                limb(d, made, "match the avatar's legs")
            )
        }
    };
    format!(
        "fitted '{}' ({} vertices) onto avatar '{}' ({:.2} m tall)\n\
         \x20 units:   {} ({how_units})\n\
         \x20 up:      {} ({})\n\
         \x20 mirrored left/right: {}{}\n\
         \x20 scale:   {:.3} about the garment's centre{}\n\
         \x20 offset:  ({:.3}, {:.3}, {:.3}) m of the garment's centre{}\n\
         \x20 sleeves: {sleeves}\n{legs}\
         \x20 near the body: {:.0} % of its area within 30 mm of the ease\n\
         \x20 vertices inside the body: {} as given, {} aligned, {relaxed}\n",
        fitted.name,
        r.vertices,
        avatar.name,
        avatar.height_m(),
        r.units.label(),
        r.up.label(),
        match (args.up, r.up) {
            (UpAxis::Auto, UpAxis::Z) => "detected from its shape; turned Y up",
            (UpAxis::Auto, _) => "detected from its shape",
            (_, UpAxis::Z) => "as given; turned Y up",
            _ => "as given",
        },
        yes_no(p.mirrored),
        if args.mirror == MirrorMode::Auto {
            " (detected from the faces' winding)"
        } else {
            " (as asked)"
        },
        p.scale,
        if args.scale.is_some() {
            " (as given)"
        } else {
            ""
        },
        p.offset_m.x,
        p.offset_m.y,
        p.offset_m.z,
        if args.offset.is_some() {
            " (as given)"
        } else {
            ""
        },
        r.fit_share * 100.0,
        r.inside_given,
        r.inside_aligned,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arguments_parse_and_bad_ones_are_refused() {
        assert_eq!(parse_units("CM"), Ok(Units::Centimetres));
        assert!(parse_units("furlong").is_err());
        assert_eq!(parse_pair("0.5, 2"), Ok((0.5, 2.0)));
        assert!(parse_pair("1").is_err());
        assert_eq!(parse_vec3("0,-0.5,1e-2"), Ok(Vec3::new(0.0, -0.5, 0.01)));
        assert!(parse_vec3("0,nan,1").is_err());
        assert_eq!(parse_mirror("flip"), Ok(MirrorMode::Flip));
        assert!(parse_mirror("x").is_err());
        assert_eq!(
            default_out(Path::new("a/shirt.obj")),
            PathBuf::from("a/shirt-fitted.obj")
        );
    }
}
