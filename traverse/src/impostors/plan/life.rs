//! A cache's life span: the frames it is expected to stay valid, which
//! divides its making cost in `UpdateNode`. Online it is extrapolated from
//! the eye's velocity and acceleration into the safety zone (the paper's
//! estimate, not conservative); offline, along a path known in advance
//! (a recorded flythrough), it is counted exactly: the frames until the
//! path's eye first leaves the zone.

use glam::DVec3;

use super::super::safety::Zone;
use super::Planner;

/// How far ahead of the last match the eye is looked for on a known path
/// before the whole path is searched.
const PATH_WINDOW: usize = 64;

impl Planner {
    /// Gives the planner the eyes of the frames to come, one per frame (a
    /// flythrough's path); empty forgets it. While the eye is on the path
    /// (equal to one of its eyes), life spans are counted along it;
    /// elsewhere they are extrapolated from the motion.
    pub fn set_known_path(&mut self, eyes: &[DVec3]) {
        self.path = eyes.to_vec();
        self.path_at = None;
    }

    /// Finds this frame's eye on the known path.
    pub(super) fn locate_on_path(&mut self, eye: DVec3) {
        self.path_at = locate(&self.path, eye, self.path_at);
    }

    /// Frames the eye at `eye` is expected to stay in `zone`, at most
    /// `cap`; 0 when it is outside.
    pub(super) fn life_span(&self, zone: &Zone, eye: DVec3, cap: u32) -> u32 {
        match self.path_at {
            Some(at) if self.path.get(at) == Some(&eye) => {
                life_along_path(zone, &self.path, at, cap)
            }
            _ => zone.frames_until_exit(eye, self.velocity, self.acceleration, cap),
        }
    }
}

/// The index of `eye` on `path`: searched first in the window after
/// `hint` (a flythrough moves forward a frame at a time), then everywhere.
/// Only an equal eye counts: a viewer off the path is not on it.
fn locate(path: &[DVec3], eye: DVec3, hint: Option<usize>) -> Option<usize> {
    let from = hint.unwrap_or(0).min(path.len());
    let to = from.saturating_add(PATH_WINDOW).min(path.len());
    path[from..to]
        .iter()
        .position(|&p| p == eye)
        .map(|i| from + i)
        .or_else(|| path.iter().position(|&p| p == eye))
}

/// Frames after `at` whose eye is still in `zone`, at most `cap` (the
/// path's end ends the count: no frame follows it); 0 when the eye at
/// `at` is outside.
fn life_along_path(zone: &Zone, path: &[DVec3], at: usize, cap: u32) -> u32 {
    if !path.get(at).is_some_and(|&eye| zone.contains(eye)) {
        return 0;
    }
    let after = path.get(at + 1..).unwrap_or(&[]);
    after
        .iter()
        .take(cap as usize)
        .take_while(|&&p| zone.contains(p))
        .count() as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(half: f64) -> Zone {
        Zone {
            min: DVec3::splat(-half),
            max: DVec3::splat(half),
        }
    }

    /// A path along x, one unit a frame, from x = start.
    fn line(start: f64, frames: usize) -> Vec<DVec3> {
        (0..frames)
            .map(|i| DVec3::new(start + i as f64, 0.0, 0.0))
            .collect()
    }

    #[test]
    fn life_along_a_path_counts_the_frames_still_inside() {
        let zone = cube(5.5);
        let path = line(-3.0, 20);
        // From x = -3: x = -2 ..= 5 are inside, 8 frames; x = 6 is out.
        assert_eq!(life_along_path(&zone, &path, 0, 1000), 8);
        assert_eq!(life_along_path(&zone, &path, 0, 3), 3, "capped");
        // The last frame inside has no frame after it inside.
        assert_eq!(life_along_path(&zone, &path, 8, 1000), 0);
        assert_eq!(life_along_path(&zone, &path, 9, 1000), 0, "outside");
        // The path ends inside: only the frames that remain.
        let short = line(-3.0, 4);
        assert_eq!(life_along_path(&zone, &short, 1, 1000), 2);
        assert_eq!(life_along_path(&zone, &short, 10, 1000), 0, "past the end");
    }

    #[test]
    fn a_path_that_turns_back_is_counted_where_motion_guesses_wrong() {
        // Out along x, then back: the motion at frame 3 says the eye
        // leaves in a few frames; the path says it stays.
        let mut path = line(0.0, 5);
        path.extend((0..5).rev().map(|i| DVec3::new(i as f64, 0.0, 0.0)));
        let zone = cube(5.5);
        assert_eq!(life_along_path(&zone, &path, 3, 1000), 6);
        let guess = zone.frames_until_exit(path[3], DVec3::X, DVec3::ZERO, 1000);
        assert_eq!(guess, 2);
    }

    #[test]
    fn the_eye_is_found_on_the_path_only_when_it_is_there() {
        let path = line(0.0, 200);
        assert_eq!(locate(&path, path[3], None), Some(3));
        assert_eq!(
            locate(&path, path[150], Some(10)),
            Some(150),
            "beyond the window"
        );
        assert_eq!(locate(&path, path[11], Some(10)), Some(11));
        assert_eq!(locate(&path, DVec3::new(0.5, 0.0, 0.0), Some(0)), None);
        assert_eq!(locate(&[], DVec3::ZERO, Some(5)), None);
        assert_eq!(
            locate(&path, path[0], Some(500)),
            Some(0),
            "a hint past the end"
        );
    }
}
