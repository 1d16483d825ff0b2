//! The scripted scenarios: `turning-car`, `pedestrians` and `city`.

use std::f64::consts::{FRAC_PI_2, PI};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::{SimObject, TruthState};
use crate::tracker::angle::wrap;

/// Which drive to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scenario {
    /// A car making a sharp 90-degree left turn among a few other cars (the paper's Figure 2).
    TurningCar,
    /// Pedestrians crossing and walking side by side, with short occlusions.
    Pedestrians,
    /// All seven nuScenes classes, dozens of objects, misses, false positives and heading flips.
    City,
}

impl crate::tracker::choice::Choice for Scenario {
    const VALUES: &'static [Self] = &Scenario::ALL;

    fn name(self) -> &'static str {
        Scenario::name(self)
    }

    fn description(self) -> &'static str {
        Scenario::description(self)
    }
}

impl Scenario {
    /// Every scenario, in the order the help lists them.
    pub const ALL: [Scenario; 3] = [Scenario::TurningCar, Scenario::Pedestrians, Scenario::City];

    /// What the drive shows (the help's line).
    pub fn description(self) -> &'static str {
        match self {
            Scenario::TurningCar => {
                "A car making a sharp 90-degree left turn among a few other cars (the paper's \
                 Figure 2)"
            }
            Scenario::Pedestrians => {
                "Pedestrians crossing and walking side by side, with short occlusions"
            }
            Scenario::City => {
                "All seven nuScenes classes, dozens of objects, misses, false positives and \
                 heading flips"
            }
        }
    }

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::TurningCar => "turning-car",
            Scenario::Pedestrians => "pedestrians",
            Scenario::City => "city",
        }
    }
}

/// Simulation settings; the defaults are `probmot simulate`'s (with the city scenario).
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// Scenario.
    pub scenario: Scenario,
    /// Random seed; the same options give a byte-identical file.
    pub seed: u64,
    /// Number of frames.
    pub frames: u32,
    /// Number of objects (city: total objects; others: extra background objects).
    pub objects: Option<u32>,
    /// Frame rate in Hz.
    pub rate_hz: f64,
    /// Write the detections in the moving `base_link` frame of a simulated ego vehicle, with
    /// its transforms on `/tf` (see [`super::ego`]); the ground truth stays in `map`.
    pub ego_frame: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            scenario: Scenario::City,
            seed: 1,
            frames: 40,
            objects: None,
            rate_hz: 2.0,
            ego_frame: false,
        }
    }
}

impl SimOptions {
    /// Frame period in seconds.
    pub fn dt(&self) -> f64 {
        1.0 / self.rate_hz
    }
}

#[allow(clippy::too_many_arguments)]
/// Object with a constant-turn-rate motion script: a list of `(from_frame, speed, yaw_rate)`.
fn scripted(
    id: u64,
    label: &'static str,
    size: [f64; 3],
    start: [f64; 3],
    yaw0: f64,
    script: &[(u32, f64, f64)],
    frames: u32,
    dt: f64,
) -> SimObject {
    let mut states = Vec::with_capacity(frames as usize);
    let (mut x, mut y, z) = (start[0], start[1], start[2]);
    let mut yaw = yaw0;
    for f in 0..frames {
        let (_, speed, rate) = script
            .iter()
            .rev()
            .find(|(from, _, _)| *from <= f)
            .copied()
            .unwrap_or((0, 0.0, 0.0));
        states.push(Some(TruthState {
            center: [x, y, z],
            yaw: wrap(yaw),
            velocity: [speed * yaw.cos(), speed * yaw.sin(), 0.0],
            yaw_rate: rate,
        }));
        // Exact arc integration over one frame.
        let dyaw = rate * dt;
        if dyaw.abs() < 1e-12 {
            x += speed * dt * yaw.cos();
            y += speed * dt * yaw.sin();
        } else {
            let r = speed / rate;
            x += r * ((yaw + dyaw).sin() - yaw.sin());
            y += r * (yaw.cos() - (yaw + dyaw).cos());
        }
        yaw += dyaw;
    }
    SimObject {
        id,
        label,
        size,
        occluded: vec![false; frames as usize],
        states,
    }
}

const CAR: [f64; 3] = [4.6, 1.9, 1.7];
const PED: [f64; 3] = [0.7, 0.6, 1.75];

/// Builds the true objects of a scenario.
pub fn objects(opts: &SimOptions) -> Vec<SimObject> {
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    match opts.scenario {
        Scenario::TurningCar => turning_car(opts),
        Scenario::Pedestrians => pedestrians(opts, &mut rng),
        Scenario::City => city(opts, &mut rng),
    }
}

/// The turning car (the paper's Figure 2) and its background traffic.
fn turning_car(opts: &SimOptions) -> Vec<SimObject> {
    let n = opts.frames;
    let dt = opts.dt();
    // The turning car: 10 m/s along +x, then a 90-degree left turn over 3 seconds
    // (about 19 m radius), then along +y.
    let turn_start = n / 4;
    let turn_frames = (3.0 / dt).round().max(1.0) as u32;
    let rate = FRAC_PI_2 / (turn_frames as f64 * dt);
    let mut v = vec![scripted(
        1,
        "car",
        CAR,
        [-45.0, -2.0, 0.9],
        0.0,
        &[
            (0, 10.0, 0.0),
            (turn_start, 10.0, rate),
            (turn_start + turn_frames, 10.0, 0.0),
        ],
        n,
        dt,
    )];
    // Background traffic: oncoming and crossing cars and a parked one.
    let extra = opts.objects.unwrap_or(4);
    for i in 0..extra {
        let id = 2 + i as u64;
        let lane = (i % 4) as f64;
        let obj = match i % 4 {
            0 => scripted(
                id,
                "car",
                CAR,
                [60.0, 2.0, 0.9],
                PI,
                &[(0, 9.0, 0.0)],
                n,
                dt,
            ),
            1 => scripted(
                id,
                "car",
                CAR,
                [8.0, -30.0 - 5.0 * lane, 0.9],
                FRAC_PI_2,
                &[(0, 7.0, 0.0)],
                n,
                dt,
            ),
            2 => scripted(
                id,
                "car",
                CAR,
                [-20.0, 8.0, 0.9],
                0.0,
                &[(0, 0.0, 0.0)],
                n,
                dt,
            ),
            _ => scripted(
                id,
                "car",
                CAR,
                [-70.0 - 10.0 * i as f64, -2.0, 0.9],
                0.0,
                &[(0, 11.0, 0.0)],
                n,
                dt,
            ),
        };
        v.push(obj);
    }
    v
}

/// Pairs of pedestrians crossing, crossers, a standing person, a slow car, and `objects` more
/// walkers at random.
fn pedestrians(opts: &SimOptions, rng: &mut ChaCha8Rng) -> Vec<SimObject> {
    let n = opts.frames;
    let dt = opts.dt();
    let mut v = Vec::new();
    let mut id = 1;
    // Two pairs walking side by side, 0.9 m apart, crossing each other's path.
    for (k, (x0, y0, yaw)) in [(-10.0, -1.0, 0.0), (10.0, 3.0, PI)]
        .into_iter()
        .enumerate()
    {
        for side in 0..2 {
            let off = 0.9 * side as f64;
            let start = if k == 0 {
                [x0, y0 + off, 0.9]
            } else {
                [x0, y0 - off, 0.9]
            };
            v.push(scripted(
                id,
                "pedestrian",
                PED,
                start,
                yaw,
                &[(0, 1.4, 0.0)],
                n,
                dt,
            ));
            id += 1;
        }
    }
    // Crossers on a diagonal, one turning slowly.
    v.push(scripted(
        id,
        "pedestrian",
        PED,
        [-6.0, -8.0, 0.9],
        0.8,
        &[(0, 1.2, 0.0), (n / 2, 1.2, 0.15)],
        n,
        dt,
    ));
    id += 1;
    v.push(scripted(
        id,
        "pedestrian",
        PED,
        [5.0, -9.0, 0.9],
        2.2,
        &[(0, 1.5, 0.0)],
        n,
        dt,
    ));
    id += 1;
    // A standing person and a slow car passing by.
    v.push(scripted(
        id,
        "pedestrian",
        PED,
        [0.0, 6.0, 0.9],
        -0.3,
        &[(0, 0.0, 0.0)],
        n,
        dt,
    ));
    id += 1;
    v.push(scripted(
        id,
        "car",
        CAR,
        [-40.0, -6.0, 0.9],
        0.0,
        &[(0, 5.0, 0.0)],
        n,
        dt,
    ));
    random_walkers(&mut v, id, opts.objects.unwrap_or(0), opts, rng);
    // Short occlusions: the second person of each pair is hidden for 2 frames when the
    // pairs pass each other, and a crosser for 1 frame.
    let mid = (n / 2) as usize;
    for (obj, frames) in [(1usize, 2usize), (3, 2), (4, 1)] {
        for f in mid..(mid + frames).min(n as usize) {
            v[obj].occluded[f] = true;
        }
    }
    v
}

/// Adds `extra` pedestrians walking straight from random places, ids after `last_id`.
fn random_walkers(
    v: &mut Vec<SimObject>,
    last_id: u64,
    extra: u32,
    opts: &SimOptions,
    rng: &mut ChaCha8Rng,
) {
    let mut id = last_id;
    for _ in 0..extra {
        id += 1;
        let x0 = rng.random_range(-15.0..15.0);
        let y0 = rng.random_range(-15.0..15.0);
        let yaw = rng.random_range(-PI..PI);
        v.push(scripted(
            id,
            "pedestrian",
            PED,
            [x0, y0, 0.9],
            yaw,
            &[(0, rng.random_range(0.8..1.8), 0.0)],
            opts.frames,
            opts.dt(),
        ));
    }
}

/// Per-class size, typical speed and process noise (std of the per-frame velocity change, m/s).
pub fn class_profile(label: &str) -> ([f64; 3], f64, f64) {
    match label {
        "car" => (CAR, 8.0, 0.25),
        "truck" => ([7.5, 2.6, 3.2], 6.0, 0.2),
        "bus" => ([11.0, 2.9, 3.4], 5.0, 0.15),
        "trailer" => ([10.0, 2.7, 3.6], 4.0, 0.1),
        "motorcycle" => ([2.1, 0.8, 1.5], 7.0, 0.3),
        "bicycle" => ([1.8, 0.6, 1.3], 4.0, 0.2),
        _ => (PED, 1.3, 0.12),
    }
}

const CITY_CLASSES: [(&str, f64); 7] = [
    ("car", 0.45),
    ("pedestrian", 0.25),
    ("truck", 0.08),
    ("bicycle", 0.06),
    ("motorcycle", 0.05),
    ("bus", 0.05),
    ("trailer", 0.06),
];

fn city(opts: &SimOptions, rng: &mut ChaCha8Rng) -> Vec<SimObject> {
    let n = opts.frames as usize;
    let dt = opts.dt();
    let count = opts.objects.unwrap_or(40);
    let mut v = Vec::with_capacity(count as usize);
    for i in 0..count {
        let u: f64 = rng.random();
        let mut acc = 0.0;
        let mut label = "car";
        for (l, p) in CITY_CLASSES {
            acc += p;
            if u < acc {
                label = l;
                break;
            }
        }
        let (size, speed, q_std) = class_profile(label);
        let jitter = |rng: &mut ChaCha8Rng| 1.0 + 0.05 * rng.random_range(-1.0..1.0);
        let size = [
            size[0] * jitter(rng),
            size[1] * jitter(rng),
            size[2] * jitter(rng),
        ];
        // Lifetime: most objects live through a long part of the log.
        let len = rng.random_range((n / 3).max(1)..=n);
        let birth = rng.random_range(0..=(n - len));
        let parked = rng.random::<f64>() < 0.2;
        let yaw0: f64 = rng.random_range(-PI..PI);
        let s0 = if parked {
            0.0
        } else {
            speed * rng.random_range(0.6..1.3)
        };
        let mut vel = [s0 * yaw0.cos(), s0 * yaw0.sin()];
        let mut pos = [
            rng.random_range(-60.0..60.0),
            rng.random_range(-60.0..60.0),
            size[2] / 2.0 + rng.random_range(-0.2..0.2),
        ];
        let mut yaw = yaw0;
        let acc_noise = Normal::new(0.0, q_std).unwrap();
        let mut states = vec![None; n];
        let mut prev_yaw = yaw;
        for (f, st) in states.iter_mut().enumerate().skip(birth).take(len) {
            let speed_now = vel[0].hypot(vel[1]);
            if speed_now > 0.5 {
                yaw = vel[1].atan2(vel[0]);
            }
            let yaw_rate = if f > birth {
                wrap(yaw - prev_yaw) / dt
            } else {
                0.0
            };
            *st = Some(TruthState {
                center: pos,
                yaw: wrap(yaw),
                velocity: [vel[0], vel[1], 0.0],
                yaw_rate,
            });
            prev_yaw = yaw;
            pos[0] += vel[0] * dt;
            pos[1] += vel[1] * dt;
            if !parked {
                vel[0] += acc_noise.sample(rng);
                vel[1] += acc_noise.sample(rng);
            }
        }
        v.push(SimObject {
            id: 1 + i as u64,
            label,
            size,
            occluded: vec![false; n],
            states,
        });
    }
    v
}
