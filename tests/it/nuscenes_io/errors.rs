//! Errors of import and export name the file and the token or scene where they failed.

use super::*;

/// Copies the fixture tables to a temporary directory, for editing.
fn fixture_copy() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for e in std::fs::read_dir(fixtures()).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), dir.path().join(e.file_name())).unwrap();
    }
    dir
}

fn import_err(meta: &Path, results: &Path, out: &Path) -> String {
    let o = probmot(&[
        "import",
        "nuscenes",
        "--detections",
        s(results),
        "--meta",
        s(meta),
        "-o",
        s(out),
    ]);
    assert!(!o.status.success(), "import should have failed");
    let no_files = std::fs::read_dir(out)
        .map(|d| d.count() == 0)
        .unwrap_or(true);
    assert!(no_files, "a failed import left files in {}", out.display());
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn import_errors_name_the_file_and_token() {
    // A results token that is not a sample.
    let t = fixture_copy();
    let mut r = load("results.json");
    r["results"]["sample-zz"] = json!([]);
    let rp = t.path().join("results.json");
    std::fs::write(&rp, serde_json::to_vec(&r).unwrap()).unwrap();
    let e = import_err(t.path(), &rp, &t.path().join("out1"));
    assert!(
        e.contains("sample-zz") && e.contains("results.json") && e.contains("sample.json"),
        "{e}"
    );

    // Missing scene.json.
    let t = fixture_copy();
    std::fs::remove_file(t.path().join("scene.json")).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(e.contains("scene.json"), "{e}");

    // Annotations without the instance table.
    let t = fixture_copy();
    std::fs::remove_file(t.path().join("instance.json")).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(e.contains("instance.json"), "{e}");

    // A broken sample chain.
    let t = fixture_copy();
    let text = std::fs::read_to_string(t.path().join("sample.json")).unwrap();
    let text = text.replace("\"next\": \"sample-a3\"", "\"next\": \"sample-gone\"");
    std::fs::write(t.path().join("sample.json"), text).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(
        e.contains("sample-gone") && e.contains("sample.json") && e.contains("scene-0001"),
        "{e}"
    );

    // An annotation of an unknown instance.
    let t = fixture_copy();
    let text = std::fs::read_to_string(t.path().join("sample_annotation.json")).unwrap();
    let text = text.replacen("\"inst-ped-1\"", "\"inst-nobody\"", 1);
    std::fs::write(t.path().join("sample_annotation.json"), text).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(
        e.contains("inst-nobody") && e.contains("instance.json"),
        "{e}"
    );

    // A sample without a LIDAR_TOP key frame (scene-0003 has no sample_data).
    let t = fixture_copy();
    let o = probmot(&[
        "import",
        "nuscenes",
        "--detections",
        s(&t.path().join("results.json")),
        "--meta",
        s(t.path()),
        "-o",
        s(&t.path().join("o")),
        "--scene",
        "scene-0003",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("sample-c1") && e.contains("sample_data.json"),
        "{e}"
    );
}

/// Writes a minimal MCAP with one Tracks3D message at `stamp` on /tracks and, optionally, the
/// samples metadata record naming `sample-x` at `sample_stamp`.
fn write_tracks_file(path: &Path, stamp: u64, score: f64, sample_stamp: Option<u64>) {
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let sid = w
        .add_schema(msgs::TRACKS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)
        .unwrap();
    let cid = w
        .add_channel(sid, "/tracks", "protobuf", &BTreeMap::new())
        .unwrap();
    if let Some(at) = sample_stamp {
        w.write_metadata(&mcap::records::Metadata {
            name: SAMPLES_METADATA.into(),
            metadata: [(at.to_string(), "sample-x".to_string())].into(),
        })
        .unwrap();
    }
    let msg = Tracks3D {
        stamp,
        frame_id: "nuscenes_global".into(),
        tracks: vec![Track3D {
            id: 1,
            label: "car".into(),
            center: Some(msgs::v3([1.0, 2.0, 3.0])),
            size: Some(msgs::Size3 {
                length: 4.0,
                width: 2.0,
                height: 1.5,
            }),
            score,
            ..Default::default()
        }],
    };
    let mut buf = Vec::new();
    msgs::encode_into(&msg, &mut buf);
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id: cid,
            sequence: 0,
            log_time: stamp,
            publish_time: stamp,
        },
        &buf,
    )
    .unwrap();
    w.finish().unwrap();
}

#[test]
fn export_refuses_nan_scores_foreign_files_and_repeated_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.json");

    let nan = dir.path().join("nan.mcap");
    write_tracks_file(&nan, 1_000, f64::NAN, Some(1_000));
    let o = probmot(&["export", "nuscenes", s(&nan), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("NaN") && e.contains("nan.mcap") && e.contains("sample-x"),
        "{e}"
    );
    assert!(!out.exists());

    let foreign = dir.path().join("foreign.mcap");
    write_tracks_file(&foreign, 1_000, 0.5, None);
    let o = probmot(&["export", "nuscenes", s(&foreign), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains(SAMPLES_METADATA) && e.contains("foreign.mcap"),
        "{e}"
    );

    let ok = dir.path().join("ok.mcap");
    write_tracks_file(&ok, 1_000, 0.5, Some(1_000));
    let o = probmot(&["export", "nuscenes", s(&ok), s(&ok), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("sample-x") && e.contains("both"), "{e}");
    probmot_ok(&["export", "nuscenes", s(&ok), "-o", s(&out), "--use-camera"]);
    let (raw, sub) = read_submission(&out);
    assert_eq!(raw["meta"]["use_camera"], true);
    assert_eq!(sub.results["sample-x"][0].size, [2.0, 4.0, 1.5]);

    // A frame whose stamp is not a sample of the scene.
    let off = dir.path().join("off.mcap");
    write_tracks_file(&off, 1_000, 0.5, Some(2_000));
    let o = probmot(&["export", "nuscenes", s(&off), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("stamp 1000") && e.contains("off.mcap"), "{e}");

    // --meta checks each input's scene against the tables.
    let o = probmot(&[
        "export",
        "nuscenes",
        s(&ok),
        "-o",
        s(&out),
        "--meta",
        s(&fixtures()),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("scene_token") && e.contains("ok.mcap"), "{e}");
}
