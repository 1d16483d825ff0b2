use probmot::tracker::{Box3, Detection, Tracker, TrackerConfig, TrackReport};
use std::f64::consts::FRAC_PI_2;

const HALF_SECOND_NS: u64 = 500_000_000;

fn car_box(x: f64, y: f64, yaw: f64) -> Box3 {
    Box3 { center: [x, y, 0.8], yaw, size: [4.5, 1.9, 1.6] }
}

struct Lcg(u64);
impl Lcg {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn sym(&mut self, a: f64) -> f64 { (2.0 * self.next_f64() - 1.0) * a }
}

/// speeds per frame (m/s), turn frames
fn trajectory(speeds: &[f64], turn_start: usize, turn_frames: usize) -> Vec<(f64, f64, f64)> {
    let mut out = vec![];
    let (mut x, mut y, mut yaw) = (0.0f64, 0.0f64, 0.0f64);
    let rate = FRAC_PI_2 / turn_frames as f64;
    for (i, v) in speeds.iter().enumerate() {
        out.push((x, y, yaw));
        let s = v * 0.5;
        if i >= turn_start && i < turn_start + turn_frames {
            // arc
            let r = s / rate;
            x += r * ((yaw + rate).sin() - yaw.sin());
            y -= r * ((yaw + rate).cos() - yaw.cos());
            yaw += rate;
        } else {
            x += s * yaw.cos();
            y += s * yaw.sin();
        }
    }
    out
}

fn run(preset: &str, traj: &[(f64, f64, f64)], noise: f64) -> Vec<Vec<TrackReport>> {
    let mut t = Tracker::new(TrackerConfig::preset(preset).unwrap()).unwrap();
    let car = t.class_id("car").unwrap();
    let mut rng = Lcg(42);
    let mut all = vec![];
    for (i, &(x, y, yaw)) in traj.iter().enumerate() {
        let d = Detection { bbox: car_box(x + rng.sym(noise), y + rng.sym(noise), yaw + rng.sym(noise * 0.2)), class: car, score: 0.9 };
        let r = t.step(i as u64 * HALF_SECOND_NS, &[d]).unwrap().to_vec();
        let mut line = format!("{preset} f{i:2} det=({x:6.2},{y:6.2},{:5.1}deg)", yaw.to_degrees());
        for rep in &r {
            let prev = all.last().and_then(|p: &Vec<TrackReport>| p.iter().find(|q| q.id == rep.id).copied());
            let miss = prev.map(|p| {
                let px = p.bbox.center[0] + p.velocity[0] * 0.5;
                let py = p.bbox.center[1] + p.velocity[1] * 0.5;
                (d.bbox.center[0] - px).hypot(d.bbox.center[1] - py)
            });
            line += &format!(" id{} h{} fsu{} miss={:?}", rep.id, rep.hits, rep.frames_since_update, miss.map(|m| (m * 100.0).round() / 100.0));
        }
        eprintln!("{line}");
        all.push(r);
    }
    all
}

#[test]
fn explore() {
    let spec = std::env::var("SPEC").unwrap_or_default();
    let v: Vec<f64> = spec.split(',').filter(|s| !s.is_empty()).map(|s| s.parse().unwrap()).collect();
    let (n1, n_turn, n2, v0, v1, noise) = (v[0] as usize, v[1] as usize, v[2] as usize, v[3], v[4], v[5]);
    let n = n1 + n_turn + n2;
    let mut speeds: Vec<f64> = (0..n).map(|i| if i < n1 { v0 + (v1 - v0) * i as f64 / (n1 as f64 - 1.0).max(1.0) } else { v1 }).collect();
    if let Ok(after) = std::env::var("AFTER") { for (j, a) in after.split(',').enumerate() { speeds[n1 + n_turn + j] = a.parse().unwrap(); } }
    let traj = trajectory(&speeds, n1, n_turn);
    run("nuscenes-chiu2019", &traj, noise);
    run("ab3dmot", &traj, noise);
}
