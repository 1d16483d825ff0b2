//! Where `eval --events` finds the box of an event ([`EventBoxes`]): in whole scenes (what the
//! KITTI protocol reads) or in the nuScenes protocol's columns loaded with their geometry
//! ([`super::columns::load_columns`] with `geometry`), so that a long log's events need about
//! 80 bytes per box instead of a whole box.

use super::columns::ColumnScene;
use super::events::{BoxAt, EventBoxes, Protocol};
use super::kitti_box::KittiFields;
use super::scene::Scene;

fn box_at(b: &impl KittiFields) -> BoxAt {
    let b3 = b.box3();
    BoxAt {
        id: b.id(),
        center: b3.center,
        size: b3.size,
        yaw: b3.yaw,
    }
}

/// Whole boxes, or the KITTI protocol's ([`super::kitti_box::KittiBox`]): both carry the fields
/// either protocol's lookup reads.
impl<B: KittiFields> EventBoxes for [Scene<B>] {
    fn name(&self, scene: usize) -> &str {
        &self[scene].name
    }

    fn stamp(&self, scene: usize, frame: usize) -> u64 {
        self[scene].frames[frame].0
    }

    fn logs(&self) -> usize {
        self.len()
    }

    fn truth(&self, (s, f): (usize, usize), id: u64, class: &str, p: Protocol) -> Option<BoxAt> {
        let boxes = &self.get(s)?.frames.get(f)?.1;
        let found = match p {
            Protocol::Nuscenes => boxes.iter().find(|b| b.id() == id && b.label() == class),
            Protocol::Kitti => boxes
                .iter()
                .find(|b| b.label() != "dontcare" && b.truth_track_id() == id as i64),
        };
        found.map(box_at)
    }

    fn track(&self, (s, f): (usize, usize), id: u64, class: &str, p: Protocol) -> Option<BoxAt> {
        let boxes = &self.get(s)?.frames.get(f)?.2;
        boxes
            .iter()
            .find(|b| b.id() == id && (p == Protocol::Kitti || b.label() == class))
            .map(box_at)
    }
}

/// Columns hold the nuScenes protocol's boxes only: the lookups are the nuScenes ones (id and
/// class), and find nothing in columns loaded without their geometry.
impl EventBoxes for [ColumnScene] {
    fn name(&self, scene: usize) -> &str {
        &self[scene].name
    }

    fn stamp(&self, scene: usize, frame: usize) -> u64 {
        self[scene].stamps[frame]
    }

    fn logs(&self) -> usize {
        self.len()
    }

    fn truth(&self, (s, f): (usize, usize), id: u64, class: &str, _: Protocol) -> Option<BoxAt> {
        let c = self.get(s)?;
        column_box(&c.truth, f, id, c.label_index(class)?)
    }

    fn track(&self, (s, f): (usize, usize), id: u64, class: &str, _: Protocol) -> Option<BoxAt> {
        let c = self.get(s)?;
        column_box(&c.tracks, f, id, c.label_index(class)?)
    }
}

fn column_box(side: &super::columns::Side, f: usize, id: u64, label: u16) -> Option<BoxAt> {
    if f + 1 >= side.at.len() {
        return None;
    }
    let i = side
        .frame(f)
        .find(|&i| side.id[i] == id && side.label[i] == label)?;
    let [z, l, w, h, yaw] = *side.geometry.get(i)?;
    Some(BoxAt {
        id,
        center: [side.xy[i][0], side.xy[i][1], z],
        size: [l, w, h],
        yaw,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::LabelledBox;

    fn b(id: u64, label: &str, x: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: label.into(),
            center: [x, 2.0 * x, 0.5],
            size: [4.0, 2.0, 1.5 + x],
            yaw: 0.1 * x,
            score: 0.7,
            ..Default::default()
        }
    }

    /// The columns with geometry find every box the whole scenes find, with the same geometry,
    /// and nothing where the scenes find nothing.
    #[test]
    fn columns_find_the_boxes_the_scenes_find() {
        let scenes = [Scene {
            name: "log.mcap".into(),
            frames: vec![
                (
                    10,
                    vec![b(1, "car", 1.0), b(1, "bus", 2.0)],
                    vec![b(7, "car", 3.0)],
                ),
                (20, vec![], vec![b(7, "car", 4.0), b(8, "pedestrian", 5.0)]),
            ],
        }];
        let columns = [ColumnScene::from_scene_with_geometry(&scenes[0])];
        let (s, c) = (&scenes[..], &columns[..]);
        let p = Protocol::Nuscenes;
        assert_eq!((c.logs(), c.name(0), c.stamp(0, 1)), (1, "log.mcap", 20));
        for f in 0..3 {
            for id in [1, 7, 8, 9] {
                for class in ["car", "bus", "pedestrian", "truck"] {
                    let at = (0, f);
                    assert_eq!(s.truth(at, id, class, p), c.truth(at, id, class, p));
                    assert_eq!(s.track(at, id, class, p), c.track(at, id, class, p));
                }
            }
        }
        let bus = c.truth((0, 0), 1, "bus", p).unwrap();
        assert_eq!(
            (bus.center, bus.size, bus.yaw),
            ([2.0, 4.0, 0.5], [4.0, 2.0, 3.5], 0.2)
        );
        // Without the geometry the columns place nothing.
        let bare = [ColumnScene::from_scene(&scenes[0])];
        assert_eq!(bare[..].truth((0, 0), 1, "bus", p), None);
    }
}
