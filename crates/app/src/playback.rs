//! Motion playback: which motion, the current time, play/pause, speed and looping.

/// Slowest playback speed (× real time).
pub const MIN_SPEED: f32 = 0.1;
/// Fastest playback speed (× real time).
pub const MAX_SPEED: f32 = 4.0;

/// Playback state of the timeline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Playback {
    /// Index of the shown motion in the avatar's motion list.
    pub motion: usize,
    /// Current time in seconds, in `[0, duration]`.
    pub time_secs: f32,
    /// Whether time advances each frame. Default false: the app opens paused, so that a
    /// freshly opened app does not redraw (a full core on a software renderer) until asked.
    pub playing: bool,
    /// Speed multiplier in [`MIN_SPEED`, `MAX_SPEED`]; default 1.
    pub speed: f32,
    /// Wrap to the start at the end (otherwise stop). Default true.
    pub looping: bool,
}

impl Default for Playback {
    fn default() -> Self {
        Self {
            motion: 0,
            time_secs: 0.0,
            playing: false,
            speed: 1.0,
            looping: true,
        }
    }
}

impl Playback {
    /// Advances by `dt_secs` of wall-clock time for a motion lasting `duration_secs`; returns
    /// true when the shown time changed.
    pub fn advance(&mut self, dt_secs: f32, duration_secs: f32) -> bool {
        let duration = if duration_secs.is_finite() {
            duration_secs.max(0.0)
        } else {
            0.0
        };
        if !self.playing || duration <= 0.0 || !(dt_secs.is_finite() && dt_secs > 0.0) {
            return false;
        }
        let before = self.time_secs;
        // Long stalls (e.g. a dragged window) do not jump more than a quarter second.
        let step = dt_secs.min(0.25) * self.speed.clamp(MIN_SPEED, MAX_SPEED);
        let mut t = self.time_secs + step;
        if t > duration {
            if self.looping {
                t = t.rem_euclid(duration);
            } else {
                t = duration;
                self.playing = false;
            }
        }
        self.time_secs = t;
        self.time_secs != before
    }

    /// Jumps to `time_secs`, clamped to `[0, duration_secs]` (NaN goes to 0).
    pub fn seek(&mut self, time_secs: f32, duration_secs: f32) {
        let duration = if duration_secs.is_finite() {
            duration_secs.max(0.0)
        } else {
            0.0
        };
        self.time_secs = if time_secs.is_finite() {
            time_secs.clamp(0.0, duration)
        } else {
            0.0
        };
    }

    /// Shows motion `index` (clamped to `count` motions) from its start.
    pub fn select_motion(&mut self, index: usize, count: usize) {
        self.motion = index.min(count.saturating_sub(1));
        self.time_secs = 0.0;
    }

    /// Frame index at `fps` for the current time.
    pub fn frame_index(&self, fps: f32) -> usize {
        if fps.is_finite() && fps > 0.0 {
            (self.time_secs * fps).round().max(0.0) as usize
        } else {
            0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advance_loops_and_respects_speed() {
        let mut p = Playback {
            speed: 2.0,
            playing: true,
            ..Default::default()
        };
        assert!(p.advance(0.1, 1.0));
        assert!((p.time_secs - 0.2).abs() < 1e-6);
        p.seek(0.95, 1.0);
        p.advance(0.05, 1.0);
        assert!(p.time_secs < 0.1, "{}", p.time_secs);
        assert!(!p.advance(f32::NAN, 1.0));
        assert!(!p.advance(0.1, 0.0));
    }

    #[test]
    fn without_looping_it_stops_at_the_end() {
        let mut p = Playback {
            looping: false,
            playing: true,
            ..Default::default()
        };
        p.seek(0.9, 1.0);
        p.advance(0.2, 1.0);
        assert_eq!(p.time_secs, 1.0);
        assert!(!p.playing);
    }

    #[test]
    fn starts_paused() {
        let mut p = Playback::default();
        assert!(!p.playing);
        assert!(!p.advance(0.1, 1.0), "no time passes until play is pressed");
        assert_eq!(p.time_secs, 0.0);
    }

    #[test]
    fn seek_and_select_clamp() {
        let mut p = Playback::default();
        p.seek(5.0, 2.0);
        assert_eq!(p.time_secs, 2.0);
        p.seek(f32::NAN, 2.0);
        assert_eq!(p.time_secs, 0.0);
        p.select_motion(9, 3);
        assert_eq!(p.motion, 2);
        p.seek(1.0, 2.0);
        assert_eq!(p.frame_index(30.0), 30);
    }
}
