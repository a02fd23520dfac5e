//! Tours: the camera flies through a list of viewpoints in order, pausing at each. Between two
//! viewpoints the eye moves along the straight line lifted into an arch just high enough to
//! clear the terrain (it flies up over a hill rather than through it), heading and pitch turn
//! by the shortest arc, and all of it is eased (smootherstep, Perlin 2002, "Improving noise",
//! eq. 2: 6t⁵ − 15t⁴ + 10t³) so the camera starts and stops without a jolt and its speed is
//! continuous at the viewpoints.

use super::camera::{Camera, Projection};

/// Heights of the terrain below scene points (`None` off the terrain).
pub type Ground<'a> = &'a dyn Fn(f32, f32) -> Option<f32>;

/// How fast a tour goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TourPace {
    /// Metres per second the eye moves at (on average over a leg).
    pub speed: f32,
    /// Degrees per second the view turns at (on average over a leg).
    pub turn_rate: f32,
    /// Shortest and longest flight between two viewpoints, in seconds.
    pub leg_s: (f32, f32),
    /// Seconds the camera rests at each viewpoint.
    pub dwell_s: f32,
    /// Metres the eye keeps above the terrain while flying (less near a viewpoint that is
    /// closer to the ground, such as a walking eye height).
    pub clearance: f32,
}

impl Default for TourPace {
    fn default() -> Self {
        TourPace { speed: 60.0, turn_rate: 45.0, leg_s: (2.0, 10.0), dwell_s: 4.0, clearance: 5.0 }
    }
}

/// Smootherstep: 0 at 0, 1 at 1, with zero first and second derivatives at both ends.
pub fn ease(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// The signed turn in degrees from heading `from` to heading `to` along the shorter way
/// round, within −180…180.
pub fn shortest_arc(from: f32, to: f32) -> f32 {
    let d = (to - from).rem_euclid(360.0);
    if d > 180.0 { d - 360.0 } else { d }
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// Samples along a leg checked against the terrain when its arch is planned.
const LIFT_SAMPLES: usize = 64;

/// One flight from a camera to a viewpoint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leg {
    /// Where the flight starts.
    pub from: Camera,
    /// Where it ends.
    pub to: Camera,
    /// Metres the arch rises at its middle above the straight line.
    pub lift: f32,
    /// Seconds the flight takes.
    pub duration: f32,
}

impl Leg {
    /// Plans the flight from `from` to `to`: its duration from the distance and the turn at
    /// `pace`, its arch from the terrain under the straight line.
    pub fn plan(from: Camera, to: Camera, ground: Ground, pace: &TourPace) -> Leg {
        let [ax, ay, az] = from.position;
        let [bx, by, bz] = to.position;
        let distance = ((bx - ax).powi(2) + (by - ay).powi(2) + (bz - az).powi(2)).sqrt();
        let turn = shortest_arc(from.yaw, to.yaw).abs() + (to.pitch - from.pitch).abs();
        let (shortest, longest) = pace.leg_s;
        let duration = (distance / pace.speed.max(1e-3))
            .max(turn / pace.turn_rate.max(1e-3))
            .clamp(shortest, longest.max(shortest));
        // The eye's height above the ground at the ends, so that the clearance asked for near a
        // low viewpoint is what that viewpoint has.
        let above = |x: f32, y: f32, z: f32| ground(x, y).map_or(pace.clearance, |g| z - g);
        let (ha, hb) = (above(ax, ay, az), above(bx, by, bz));
        let mut lift = 0.0f32;
        for i in 1..LIFT_SAMPLES {
            let s = i as f32 / LIFT_SAMPLES as f32;
            let Some(g) = ground(lerp(ax, bx, s), lerp(ay, by, s)) else { continue };
            // Near a low viewpoint the eye may be as low as there, between them it clears
            // the ground by the full clearance.
            let clearance = (lerp(ha, hb, s) + pace.clearance * (std::f32::consts::PI * s).sin()).min(pace.clearance);
            let wanted = g + clearance.max(0.0);
            let deficit = wanted - lerp(az, bz, s);
            if deficit > 0.0 {
                lift = lift.max(deficit / (std::f32::consts::PI * s).sin());
            }
        }
        Leg { from, to, lift, duration }
    }

    /// The camera `t` seconds into the flight (clamped to the flight).
    pub fn camera_at(&self, t: f32) -> Camera {
        let s = if self.duration > 0.0 { ease(t / self.duration) } else { 1.0 };
        let (a, b) = (&self.from, &self.to);
        let arch = self.lift * (std::f32::consts::PI * s).sin();
        let position = [
            lerp(a.position[0], b.position[0], s),
            lerp(a.position[1], b.position[1], s),
            lerp(a.position[2], b.position[2], s) + arch,
        ];
        let projection = match (a.projection, b.projection) {
            (Projection::Plan { width: wa }, Projection::Plan { width: wb }) => {
                Projection::Plan { width: lerp(wa, wb, s) }
            }
            // A change between plan and perspective happens half-way.
            _ if s < 0.5 => a.projection,
            _ => b.projection,
        };
        Camera {
            position,
            yaw: (a.yaw + shortest_arc(a.yaw, b.yaw) * s).rem_euclid(360.0),
            pitch: lerp(a.pitch, b.pitch, s),
            fov: lerp(a.fov, b.fov, s),
            roll: lerp(a.roll, b.roll, s),
            projection,
        }
    }
}

/// What a tour does at a moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TourStep {
    /// The camera to show.
    pub camera: Camera,
    /// Whether the camera moves (else it rests at a viewpoint).
    pub moving: bool,
    /// The viewpoint reached since the last step, if one was.
    pub reached: Option<usize>,
    /// Whether the tour is over (it rests at the last viewpoint).
    pub finished: bool,
    /// Seconds (on the tour's clock) of the next change when resting, for a wake-up.
    pub next_change: Option<f32>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Flying { leg: Leg, started: f32, target: usize },
    Resting { at: usize, until: f32 },
    Finished { at: usize },
}

/// A tour being played: which viewpoint it flies to or rests at. Time is given by the caller
/// in seconds on any clock that only goes forward.
#[derive(Debug, Clone, PartialEq)]
pub struct Tour {
    stops: Vec<Camera>,
    pace: TourPace,
    phase: Phase,
    /// A viewpoint reached and not yet reported by [`Tour::advance`].
    reached: Option<usize>,
}

impl Tour {
    /// Starts a tour of `stops` (at least one) at time `now`, flying from `current` to stop
    /// `first`; `None` without stops or with `first` out of range.
    pub fn start(
        stops: Vec<Camera>,
        first: usize,
        current: Camera,
        ground: Ground,
        pace: TourPace,
        now: f32,
    ) -> Option<Tour> {
        let to = *stops.get(first)?;
        let leg = Leg::plan(current, to, ground, &pace);
        Some(Tour { stops, pace, phase: Phase::Flying { leg, started: now, target: first }, reached: None })
    }

    /// Number of viewpoints.
    pub fn len(&self) -> usize {
        self.stops.len()
    }

    /// Whether the tour has no viewpoints (never: [`Tour::start`] needs one).
    pub fn is_empty(&self) -> bool {
        self.stops.is_empty()
    }

    /// The viewpoint the tour flies to or rests at.
    pub fn current(&self) -> usize {
        match self.phase {
            Phase::Flying { target, .. } => target,
            Phase::Resting { at, .. } | Phase::Finished { at } => at,
        }
    }

    /// Moves the tour on to time `now` and tells what to show.
    pub fn advance(&mut self, now: f32, ground: Ground) -> TourStep {
        loop {
            match self.phase {
                Phase::Flying { leg, started, target } if now - started >= leg.duration => {
                    self.reached = Some(target);
                    self.phase = Phase::Resting { at: target, until: started + leg.duration + self.pace.dwell_s };
                }
                Phase::Resting { at, until } if now >= until => {
                    if at + 1 < self.stops.len() {
                        let leg = Leg::plan(self.stops[at], self.stops[at + 1], ground, &self.pace);
                        self.phase = Phase::Flying { leg, started: until, target: at + 1 };
                    } else {
                        self.phase = Phase::Finished { at };
                    }
                }
                _ => break,
            }
        }
        let reached = self.reached.take();
        match self.phase {
            Phase::Flying { leg, started, .. } => TourStep {
                camera: leg.camera_at(now - started),
                moving: true,
                reached,
                finished: false,
                next_change: None,
            },
            Phase::Resting { at, until } => {
                TourStep { camera: self.stops[at], moving: false, reached, finished: false, next_change: Some(until) }
            }
            Phase::Finished { at } => {
                TourStep { camera: self.stops[at], moving: false, reached, finished: true, next_change: None }
            }
        }
    }

    /// Flies from `current` (the camera shown now) to viewpoint `target` starting at `now`
    /// (next/previous); `false` when there is no such viewpoint.
    pub fn go_to(&mut self, target: usize, current: Camera, now: f32, ground: Ground) -> bool {
        let Some(&to) = self.stops.get(target) else { return false };
        self.phase = Phase::Flying { leg: Leg::plan(current, to, ground, &self.pace), started: now, target };
        self.reached = None;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
        glam::Vec3::from(a).distance(glam::Vec3::from(b))
    }

    fn flat(_: f32, _: f32) -> Option<f32> {
        Some(100.0)
    }

    /// A ridge 80 m high along x = 0 (a Gaussian 30 m wide) on a plain at 100 m.
    fn ridge(x: f32, _: f32) -> Option<f32> {
        Some(100.0 + 80.0 * (-(x / 30.0).powi(2)).exp())
    }

    #[test]
    fn easing_starts_and_ends_at_rest() {
        assert_eq!(ease(0.0), 0.0);
        assert_eq!(ease(1.0), 1.0);
        assert!((ease(0.5) - 0.5).abs() < 1e-6);
        let slope = |t: f32| (ease(t + 1e-3) - ease(t)) / 1e-3;
        assert!(slope(0.0) < 1e-3 && slope(1.0 - 1e-3) < 1e-2 && slope(0.5) > 1.8);
        assert!((0..100).all(|i| ease(i as f32 / 100.0) <= ease((i + 1) as f32 / 100.0)));
    }

    #[test]
    fn headings_turn_the_short_way_round() {
        assert_eq!(shortest_arc(350.0, 10.0), 20.0);
        assert_eq!(shortest_arc(10.0, 350.0), -20.0);
        assert_eq!(shortest_arc(0.0, 180.0), 180.0);
        assert_eq!(shortest_arc(90.0, 90.0), 0.0);
        let leg = Leg {
            from: Camera::perspective([0.0; 3], 350.0, 0.0, 60.0),
            to: Camera::perspective([0.0; 3], 30.0, 0.0, 60.0),
            lift: 0.0,
            duration: 2.0,
        };
        // Through north (0), never through south.
        for i in 0..=20 {
            let yaw = leg.camera_at(i as f32 * 0.1).yaw;
            assert!(!(30.5..349.5).contains(&yaw), "{yaw}");
        }
        assert!((leg.camera_at(1.0).yaw - 10.0).abs() < 1e-3);
    }

    #[test]
    fn a_leg_ends_at_the_viewpoints_and_moves_smoothly() {
        let from = Camera::perspective([0.0, 0.0, 150.0], 0.0, -10.0, 60.0);
        let to = Camera::perspective([300.0, 400.0, 130.0], 90.0, 0.0, 40.0);
        let leg = Leg::plan(from, to, &flat, &TourPace::default());
        assert_eq!(leg.camera_at(0.0), from);
        let end = leg.camera_at(leg.duration);
        assert!(distance(end.position, to.position) < 1e-3 && (end.yaw - 90.0).abs() < 1e-3);
        // 500 m at 60 m/s: about 8.3 s.
        assert!((leg.duration - 500.0 / 60.0).abs() < 0.01, "{}", leg.duration);
        // No step between frames at 30 frames/s is more than twice the average step.
        let steps: Vec<f32> = (0..(leg.duration * 30.0) as usize)
            .map(|i| {
                let (a, b) = (leg.camera_at(i as f32 / 30.0), leg.camera_at((i + 1) as f32 / 30.0));
                distance(a.position, b.position)
            })
            .collect();
        let average = 500.0 / steps.len() as f32;
        assert!(steps.iter().all(|s| *s < 2.0 * average), "{steps:?}");
        // Flat ground well below: no arch.
        assert_eq!(leg.lift, 0.0);
    }

    #[test]
    fn the_flight_goes_over_a_ridge_not_through_it() {
        // Two walking viewpoints, 1.7 m above the plain on either side of the ridge.
        let from = Camera::perspective([-200.0, 0.0, 101.7], 90.0, 0.0, 60.0);
        let to = Camera::perspective([200.0, 0.0, 101.7], 90.0, 0.0, 60.0);
        let pace = TourPace::default();
        let leg = Leg::plan(from, to, &ridge, &pace);
        // The ridge top is 78.3 m above the eyes, and the eye clears it by the clearance.
        assert!(leg.lift >= 78.3 + pace.clearance - 0.1, "{}", leg.lift);
        for i in 0..=300 {
            let c = leg.camera_at(leg.duration * i as f32 / 300.0);
            let ground = ridge(c.position[0], c.position[1]).expect("ground");
            assert!(c.position[2] >= ground + 1.6, "{i}: eye {} over ground {ground}", c.position[2]);
            if c.position[0].abs() < 20.0 {
                assert!(c.position[2] >= ground + pace.clearance - 0.5, "{i}: eye {} over the ridge", c.position[2]);
            }
        }
        // The top of the arch clears the ridge by about the clearance, not by far more.
        let top = leg.camera_at(leg.duration / 2.0).position[2];
        assert!(top < 180.0 + pace.clearance + 10.0, "{top}");
    }

    #[test]
    fn a_tour_visits_every_viewpoint_in_order_and_rests_at_each() {
        let stops: Vec<Camera> =
            (0..3).map(|i| Camera::perspective([i as f32 * 100.0, 0.0, 150.0], i as f32 * 90.0, 0.0, 60.0)).collect();
        let pace = TourPace { dwell_s: 1.0, leg_s: (1.0, 1.0), ..TourPace::default() };
        let start = Camera::perspective([0.0, -100.0, 150.0], 0.0, 0.0, 60.0);
        let mut tour = Tour::start(stops.clone(), 0, start, &flat, pace, 0.0).expect("tour");
        let mut reached = Vec::new();
        let mut t = 0.0;
        let mut last = tour.advance(t, &flat);
        while !last.finished {
            t += 0.05;
            last = tour.advance(t, &flat);
            reached.extend(last.reached);
            if let Some(i) = last.reached {
                assert_eq!(last.camera, stops[i], "at {t}");
                assert!(!last.moving);
            }
            assert!(t < 20.0, "the tour never ends");
        }
        assert_eq!(reached, [0, 1, 2]);
        // Three legs of 1 s and three rests of 1 s (the tour ends after the last rest).
        assert!((t - 6.0).abs() < 0.1, "{t}");
        assert_eq!(last.camera, stops[2]);
        assert!(Tour::start(stops, 3, start, &flat, pace, 0.0).is_none());
    }

    #[test]
    fn next_and_previous_fly_from_where_the_camera_is() {
        let stops: Vec<Camera> =
            (0..3).map(|i| Camera::perspective([i as f32 * 100.0, 0.0, 150.0], 0.0, 0.0, 60.0)).collect();
        let pace = TourPace { dwell_s: 10.0, leg_s: (1.0, 1.0), ..TourPace::default() };
        let mut tour = Tour::start(stops.clone(), 0, stops[0], &flat, pace, 0.0).expect("tour");
        let step = tour.advance(0.5, &flat);
        assert!(tour.go_to(2, step.camera, 0.5, &flat));
        assert_eq!(tour.current(), 2);
        let halfway = tour.advance(1.0, &flat).camera.position[0];
        assert!((90.0..110.0).contains(&halfway), "{halfway}");
        assert_eq!(tour.advance(1.5, &flat).reached, Some(2));
        assert!(!tour.go_to(3, stops[2], 2.0, &flat));
        assert!(tour.go_to(1, stops[2], 2.0, &flat));
        assert_eq!(tour.advance(3.0, &flat).reached, Some(1));
    }
}
