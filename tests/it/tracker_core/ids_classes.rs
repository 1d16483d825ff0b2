//! Track ids and classes: stable class ids, no matching across labels, unique ids.

use super::*;

/// Class ids stay stable and distinct past the few classes looked up by a scan (labels beyond
/// the preset's use its `default` entry, each as a class of its own).
#[test]
fn class_ids_are_stable_for_many_labels() {
    let mut t = tracker("nuscenes-chiu2019");
    let labels: Vec<String> = (0..40).map(|i| format!("label{i}")).collect();
    let first: Vec<u32> = labels.iter().map(|l| t.class_id(l).unwrap()).collect();
    let again: Vec<u32> = labels
        .iter()
        .rev()
        .map(|l| t.class_id(l).unwrap())
        .collect();
    assert_eq!(first, again.into_iter().rev().collect::<Vec<_>>());
    assert_eq!(first.iter().collect::<HashSet<_>>().len(), labels.len());
    for (l, id) in labels.iter().zip(&first) {
        assert_eq!(t.label(*id), l);
    }
}

/// A car and a pedestrian detection with the same box give two tracks; each keeps matching only
/// detections of its own class.
#[test]
fn classes_never_match_across_labels() {
    let mut t = tracker("nuscenes-chiu2019");
    let car = t.class_id("car").unwrap();
    let ped = t.class_id("pedestrian").unwrap();
    assert!(car < ped);
    let b = car_box(5.0, 5.0, 0.0);

    // The pedestrian comes first in the list, but classes are processed in class-id order, so
    // the car is born first and gets id 1.
    let r = step(&mut t, 0, &[det(ped, b), det(car, b)]);
    assert_eq!(r.len(), 2, "{r:?}");
    assert_eq!((r[0].id, r[0].class, r[0].detection), (1, car, Some(1)));
    assert_eq!((r[1].id, r[1].class, r[1].detection), (2, ped, Some(0)));

    for f in 1..5 {
        let r = step(&mut t, f, &[det(ped, b), det(car, b)]);
        assert_eq!(r.len(), 2, "frame {f}: {r:?}");
        assert_eq!((r[0].id, r[0].class, r[0].detection), (1, car, Some(1)));
        assert_eq!((r[1].id, r[1].class, r[1].detection), (2, ped, Some(0)));
        assert_eq!(r[0].hits, f as u32 + 1);
        assert_eq!(r[1].hits, f as u32 + 1);
    }

    // Only a pedestrian at the place: the car track coasts, it does not take that detection.
    let r = step(&mut t, 5, &[det(ped, b)]);
    let c = r.iter().find(|x| x.id == 1).unwrap();
    let p = r.iter().find(|x| x.id == 2).unwrap();
    assert_eq!((c.frames_since_update, c.detection), (1, None));
    assert_eq!((p.frames_since_update, p.detection), (0, Some(0)));
    assert_eq!(t.live_tracks(), 2);

    // A fresh tracker: a car track, then only a pedestrian detection on top of it starts a new
    // pedestrian track instead of updating the car.
    let mut t = tracker("nuscenes-chiu2019");
    let car = t.class_id("car").unwrap();
    let ped = t.class_id("pedestrian").unwrap();
    step(&mut t, 0, &[det(car, b)]);
    let r = step(&mut t, 1, &[det(ped, b)]);
    assert_eq!(r.len(), 2, "{r:?}");
    assert_eq!(
        (r[0].id, r[0].class, r[0].hits, r[0].frames_since_update),
        (1, car, 1, 1)
    );
    assert_eq!(
        (r[1].id, r[1].class, r[1].hits, r[1].detection),
        (2, ped, 1, Some(0))
    );
}

/// Ids come from one counter over all classes: every newly seen id is larger than all earlier
/// ones, an id keeps its class, and a deleted id never comes back.
#[test]
fn ids_are_unique_within_a_run() {
    let mut t = tracker("nuscenes-chiu2019");
    let labels = ["car", "pedestrian", "bicycle", "truck"];
    let classes: Vec<u32> = labels.iter().map(|l| t.class_id(l).unwrap()).collect();
    let mut rng = Lcg(7);
    let mut class_of: HashMap<u64, u32> = HashMap::new();
    let mut max_seen = 0u64;
    let mut dead: HashSet<u64> = HashSet::new();
    for f in 0..60u64 {
        // Four objects that blink in and out, plus a clutter detection now and then.
        let mut dets = vec![];
        for (i, &c) in classes.iter().enumerate() {
            if rng.next_f64() < 0.7 {
                let x = 10.0 * i as f64 + 0.5 * f as f64 + rng.sym(0.1);
                dets.push(det(c, car_box(x, 0.0, 0.0)));
            }
        }
        if rng.next_f64() < 0.3 {
            let c = classes[(rng.next_f64() * 4.0) as usize % 4];
            dets.push(det(c, car_box(rng.sym(40.0), 30.0 + rng.sym(10.0), 0.0)));
        }
        let reports = step(&mut t, f, &dets);
        let mut ids_this_frame = HashSet::new();
        let mut new_ids = vec![];
        for r in &reports {
            assert!(
                ids_this_frame.insert(r.id),
                "id {} twice in frame {f}",
                r.id
            );
            assert!(!dead.contains(&r.id), "deleted id {} came back", r.id);
            match class_of.get(&r.id) {
                Some(&c) => assert_eq!(c, r.class, "id {} changed class", r.id),
                None => {
                    class_of.insert(r.id, r.class);
                    new_ids.push(r.id);
                }
            }
        }
        for id in new_ids {
            assert!(id > max_seen, "new id {id} not above {max_seen}");
            max_seen = max_seen.max(id);
        }
        dead.extend(t.deleted().iter().copied());
    }
    assert!(
        class_of.len() > 4,
        "the script should produce several tracks"
    );
    assert!(!dead.is_empty());
    // One counter: the largest id is the number of tracks born.
    assert!(t.stats().born >= max_seen);
}
