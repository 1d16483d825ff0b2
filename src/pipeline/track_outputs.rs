//! The optional output channels of `probmot track` beside the tracks channel:
//! `<tracks-topic>/ego` (`--tracks-frame ego`: the same tracks moved into each frame's
//! detection frame) and `--scene-topic` (`foxglove.SceneUpdate` for the Foxglove 3D panel).

use std::collections::{BTreeMap, HashSet};

use anyhow::{bail, Context, Result};
use mcap::records::MessageHeader;
use nalgebra::Isometry3;

use crate::mcapio::sink::RecordSink;
use crate::msgs::scene_update::{
    scene_update_descriptor, SceneEncoder, OUTPUT_METADATA_KEY, SCENE_UPDATE_SCHEMA,
};
use crate::msgs::track_encode::encode_tracks;
use crate::msgs::Tracks3D;
use crate::transforms::boxes::transform_tracks_into;

/// Suffix of the tracks topic for the tracks in the ego frame.
pub const EGO_TOPIC_SUFFIX: &str = "/ego";

/// Ids and buffers of the extra output channels.
pub struct ExtraOutputs {
    /// `(topic, channel id)` of the ego-frame tracks channel.
    ego: Option<(String, u16)>,
    /// `(topic, schema id, channel id)` of the scene channel.
    scene: Option<(String, u16, u16)>,
    ego_msg: Tracks3D,
    buf: Vec<u8>,
    ego_sequence: u32,
    scene_encoder: SceneEncoder,
}

/// Which extra channels a run asked for (from [`super::track::TrackOptions`]).
pub struct ExtraRequest<'a> {
    /// Topic of the tracks channel (the ego-frame topic is this plus [`EGO_TOPIC_SUFFIX`]).
    pub tracks_topic: &'a str,
    /// `--tracks-frame ego`.
    pub tracks_in_ego_frame: bool,
    /// `--scene-topic`.
    pub scene_topic: Option<&'a str>,
}

type ScanIds = (HashSet<u16>, HashSet<u16>, HashSet<String>);

fn free(used: &HashSet<u16>, taken: &[u16]) -> Option<u16> {
    (1..=u16::MAX).find(|i| !used.contains(i) && !taken.contains(i))
}

impl ExtraOutputs {
    /// Plans the extra channels: their topics must not exist in the input, and their ids are
    /// the first free ones after `tracks_ids` (the tracks channel's schema and channel ids).
    /// Nothing is planned without a tracks channel.
    pub fn new(
        opts: &ExtraRequest<'_>,
        file: &str,
        scan: Option<&ScanIds>,
        tracks_ids: Option<(u16, u16)>,
    ) -> Result<Self> {
        let mut x = ExtraOutputs {
            ego: None,
            scene: None,
            ego_msg: Tracks3D::default(),
            buf: Vec::new(),
            ego_sequence: 0,
            scene_encoder: SceneEncoder::default(),
        };
        let (Some((schemas, channels, topics)), Some((tracks_schema, tracks_channel))) =
            (scan, tracks_ids)
        else {
            return Ok(x);
        };
        let mut taken_channels = vec![tracks_channel];
        let check_topic = |topic: &str, option: &str| -> Result<()> {
            if topics.contains(topic) || topic == opts.tracks_topic {
                bail!(
                    "{file}: already has a channel on {topic}; choose another topic with {option}"
                );
            }
            Ok(())
        };
        if opts.tracks_in_ego_frame {
            let topic = format!("{}{EGO_TOPIC_SUFFIX}", opts.tracks_topic);
            check_topic(&topic, "--tracks-topic")?;
            let id = free(channels, &taken_channels).context("no free channel id in the output")?;
            taken_channels.push(id);
            x.ego = Some((topic, id));
        }
        if let Some(topic) = opts.scene_topic {
            check_topic(topic, "--scene-topic")?;
            if x.ego.as_ref().is_some_and(|(t, _)| t == topic) {
                bail!("--scene-topic {topic} is the topic of the ego-frame tracks");
            }
            let schema =
                free(schemas, &[tracks_schema]).context("no free schema id in the output")?;
            let id = free(channels, &taken_channels).context("no free channel id in the output")?;
            x.scene = Some((topic.to_string(), schema, id));
        }
        Ok(x)
    }

    /// Adds the planned channels to the output (`tracks_schema`: the `probmot.Tracks3D` schema
    /// id already added).
    pub fn add_channels(&self, w: &mut impl RecordSink, tracks_schema: u16) -> Result<()> {
        if let Some((topic, id)) = &self.ego {
            w.add_channel_with_id(*id, tracks_schema, topic, "protobuf", &BTreeMap::new())?;
        }
        if let Some((topic, schema, id)) = &self.scene {
            w.add_schema_with_id(
                *schema,
                SCENE_UPDATE_SCHEMA,
                "protobuf",
                &scene_update_descriptor(),
            )?;
            let metadata =
                BTreeMap::from([(OUTPUT_METADATA_KEY.to_string(), "tracks".to_string())]);
            w.add_channel_with_id(*id, *schema, topic, "protobuf", &metadata)?;
        }
        Ok(())
    }

    /// Writes one frame's extra messages (at the tracks' `log_time`): the tracks in the ego frame (when its transform is
    /// known; `ego` = detection frame and fixed-to-ego transform) and the scene update (with
    /// deletions for the tracks shown before and not reported now).
    pub fn write_frame(
        &mut self,
        w: &mut impl RecordSink,
        tracks: &Tracks3D,
        ego: Option<(String, Isometry3<f64>)>,
        sequence: u32,
        log_time: u64,
    ) -> Result<()> {
        let header = |channel_id| MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        };
        if let (Some((_, id)), Some((frame, iso))) = (&self.ego, ego) {
            transform_tracks_into(tracks, &iso, &frame, &mut self.ego_msg);
            let mut h = header(*id);
            h.sequence = self.ego_sequence;
            self.ego_sequence += 1;
            let ego_msg = &self.ego_msg;
            w.write_encoded(&h, &mut self.buf, |buf| encode_tracks(ego_msg, buf))?;
        }
        if let Some((_, _, id)) = &self.scene {
            let scene = &mut self.scene_encoder;
            w.write_encoded(&header(*id), &mut self.buf, |buf| {
                scene.append_frame(tracks, buf)
            })?;
        }
        Ok(())
    }
}
