//! The BVH tokenizer and parser behind [`Bvh::parse`]: hierarchy (iteratively, so deep
//! nesting cannot overflow the stack), `MOTION` header (tolerating `Frames:343` and tabs) and
//! the frame values, with 1-based line numbers in every syntax error.

use std::path::Path;

use super::bvh::{Bvh, BvhChannel, BvhJoint};
use super::units::largest_extent;
use super::{IoError, file_stem};
use crate::geometry::Vec3;

/// Token cursor over the file with 1-based line numbers.
struct Cursor<'a> {
    tokens: Vec<(usize, &'a str)>,
    at: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    fn syntax(&self, line: usize, reason: impl Into<String>) -> IoError {
        IoError::Syntax {
            format: "BVH",
            line,
            reason: reason.into(),
            path: self.path.to_path_buf(),
        }
    }

    fn last_line(&self) -> usize {
        self.tokens.last().map(|t| t.0).unwrap_or(1)
    }

    fn next(&mut self, expecting: &str) -> Result<(usize, &'a str), IoError> {
        let Some(&t) = self.tokens.get(self.at) else {
            return Err(IoError::Truncated {
                what: format!(
                    "BVH ends at line {} while expecting {expecting}",
                    self.last_line()
                ),
                path: self.path.to_path_buf(),
            });
        };
        self.at += 1;
        Ok(t)
    }

    fn expect(&mut self, word: &str) -> Result<usize, IoError> {
        let (line, t) = self.next(&format!("'{word}'"))?;
        if t.eq_ignore_ascii_case(word) {
            Ok(line)
        } else {
            Err(self.syntax(line, format!("expected '{word}', found '{t}'")))
        }
    }

    fn float(&mut self, what: &str) -> Result<f32, IoError> {
        let (line, t) = self.next(what)?;
        let v: f32 = t
            .parse()
            .map_err(|_| self.syntax(line, format!("{what}: '{t}' is not a number")))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(IoError::NonFinite {
                what: format!("{what} at line {line}"),
                path: self.path.to_path_buf(),
            })
        }
    }

    fn vec3(&mut self, what: &str) -> Result<Vec3, IoError> {
        Ok(Vec3::new(
            self.float(what)?,
            self.float(what)?,
            self.float(what)?,
        ))
    }

    /// The rest of the current line (a joint name), skipping a trailing `{`.
    fn name(&mut self, line: usize) -> Result<String, IoError> {
        let mut parts = Vec::new();
        while let Some(&(l, t)) = self.tokens.get(self.at) {
            if l != line || t == "{" {
                break;
            }
            parts.push(t);
            self.at += 1;
        }
        if parts.is_empty() {
            Err(self.syntax(line, "joint without a name"))
        } else {
            Ok(parts.join(" "))
        }
    }

    /// The value after `Key:` where the key may be glued to the colon and/or the value.
    fn keyed_value(&mut self, key: &str) -> Result<(usize, &'a str), IoError> {
        let (line, t) = self.next(key)?;
        let lower = t.to_ascii_lowercase();
        let Some(rest) = lower.strip_prefix(&key.to_ascii_lowercase()) else {
            return Err(self.syntax(line, format!("expected '{key}:', found '{t}'")));
        };
        let rest = rest.trim_start_matches(':');
        if !rest.is_empty() {
            return Ok((line, &t[t.len() - rest.len()..]));
        }
        let (line, v) = self.next(key)?;
        if v == ":" {
            self.next(key)
        } else {
            Ok((line, v.trim_start_matches(':')))
        }
    }
}

impl Bvh {
    /// Parses BVH bytes; `path` names the motion and ends error messages.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self, IoError> {
        let text = String::from_utf8_lossy(bytes);
        let tokens = text
            .lines()
            .enumerate()
            .flat_map(|(k, l)| l.split_whitespace().map(move |t| (k + 1, t)))
            .collect();
        let mut c = Cursor {
            tokens,
            at: 0,
            path,
        };
        let (line, first) = c.next("'HIERARCHY'")?;
        if !first.eq_ignore_ascii_case("HIERARCHY") {
            return Err(c.syntax(
                line,
                format!("not a BVH file: expected 'HIERARCHY', found '{first}'"),
            ));
        }
        let root_line = c.expect("ROOT")?;
        let mut joints = vec![BvhJoint {
            name: c.name(root_line)?,
            parent: None,
            offset: Vec3::zeros(),
            channels: Vec::new(),
            first_channel: 0,
            end_site: None,
        }];
        c.expect("{")?;
        let mut stack = vec![0usize];
        let mut channel_count = 0usize;
        while let Some(&top) = stack.last() {
            let (line, t) = c.next(&format!("the end of joint '{}'", joints[top].name))?;
            match t.to_ascii_uppercase().as_str() {
                "OFFSET" => joints[top].offset = c.vec3("OFFSET")?,
                "CHANNELS" => {
                    let (l, n) = c.next("a channel count")?;
                    let n: usize = n.parse().ok().filter(|&n| n <= 6).ok_or_else(|| {
                        c.syntax(l, format!("channel count '{n}' (0 to 6 expected)"))
                    })?;
                    let mut channels = Vec::with_capacity(n);
                    for _ in 0..n {
                        let (l, name) = c.next("a channel name")?;
                        let ch = BvhChannel::parse(name)
                            .ok_or_else(|| c.syntax(l, format!("unknown channel '{name}'")))?;
                        if channels.contains(&ch) {
                            return Err(c.syntax(l, format!("channel '{name}' repeated")));
                        }
                        channels.push(ch);
                    }
                    joints[top].first_channel = channel_count;
                    channel_count += n;
                    joints[top].channels = channels;
                }
                "JOINT" => {
                    let name = c.name(line)?;
                    joints.push(BvhJoint {
                        name,
                        parent: Some(top),
                        offset: Vec3::zeros(),
                        channels: Vec::new(),
                        first_channel: channel_count,
                        end_site: None,
                    });
                    c.expect("{")?;
                    stack.push(joints.len() - 1);
                }
                "END" => {
                    c.expect("Site")?;
                    c.expect("{")?;
                    c.expect("OFFSET")?;
                    joints[top].end_site = Some(c.vec3("End Site OFFSET")?);
                    c.expect("}")?;
                }
                "}" => {
                    stack.pop();
                }
                _ => {
                    return Err(c.syntax(
                        line,
                        format!("unexpected '{t}' in joint '{}'", joints[top].name),
                    ));
                }
            }
        }
        let (line, t) = c.next("'MOTION'")?;
        if t.eq_ignore_ascii_case("ROOT") {
            return Err(IoError::Unsupported {
                what: format!("a second ROOT at line {line} (one skeleton per file)"),
                path: path.to_path_buf(),
            });
        }
        if !t.eq_ignore_ascii_case("MOTION") {
            return Err(c.syntax(line, format!("expected 'MOTION', found '{t}'")));
        }
        let (line, frames) = c.keyed_value("Frames")?;
        let frames: usize = frames
            .parse()
            .map_err(|_| c.syntax(line, format!("frame count '{frames}'")))?;
        if frames == 0 {
            return Err(c.syntax(line, "the file declares 0 frames"));
        }
        c.expect("Frame")?;
        let (line, ft) = c.keyed_value("Time")?;
        let frame_time_secs: f32 = ft
            .parse()
            .map_err(|_| c.syntax(line, format!("frame time '{ft}'")))?;
        if !(frame_time_secs.is_finite() && (1e-4..=10.0).contains(&frame_time_secs)) {
            return Err(c.syntax(line, format!("frame time {ft} s is outside 0.0001..10 s")));
        }
        if channel_count == 0 {
            return Err(IoError::Unsupported {
                what: "a BVH without channels".into(),
                path: path.to_path_buf(),
            });
        }
        let expected = frames
            .checked_mul(channel_count)
            .ok_or_else(|| c.syntax(line, "frame count too large"))?;
        let remaining = c.tokens.len() - c.at;
        let mut values = Vec::with_capacity(expected.min(remaining));
        for k in 0..expected {
            let Some(&(l, t)) = c.tokens.get(c.at) else {
                return Err(IoError::Truncated {
                    what: format!(
                        "BVH declares {frames} frames of {channel_count} values, data ends in frame {} (line {})",
                        k / channel_count.max(1) + 1,
                        c.last_line()
                    ),
                    path: path.to_path_buf(),
                });
            };
            c.at += 1;
            let v: f32 = t
                .parse()
                .map_err(|_| c.syntax(l, format!("'{t}' is not a number")))?;
            if !v.is_finite() {
                return Err(IoError::NonFinite {
                    what: format!(
                        "frame {} value {} at line {l}",
                        k / channel_count + 1,
                        k % channel_count + 1
                    ),
                    path: path.to_path_buf(),
                });
            }
            values.push(v);
        }
        let mut warnings = Vec::new();
        if c.at < c.tokens.len() {
            warnings.push(format!(
                "{} values after the last declared frame ignored",
                c.tokens.len() - c.at
            ));
        }
        let mut bvh = Self {
            name: file_stem(path),
            path: path.to_path_buf(),
            joints,
            frame_time_secs,
            channel_count,
            frames,
            values,
            warnings,
            up: super::UpAxis::Auto,
        };
        let extent = largest_extent(&bvh.rest_points());
        let zero: Vec<&str> = bvh
            .joints
            .iter()
            .filter(|j| j.parent.is_some() && j.offset.norm() <= 1e-6 * extent.max(1e-3))
            .map(|j| j.name.as_str())
            .collect();
        if !zero.is_empty() {
            let msg = format!(
                "{} zero-length bones (joint on its parent): {}",
                zero.len(),
                super::gltf_avatar::short_list(&zero, 8)
            );
            bvh.warnings.push(msg);
        }
        Ok(bvh)
    }
}
