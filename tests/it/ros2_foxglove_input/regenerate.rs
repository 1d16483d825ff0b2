//! Regenerating the fixtures (needs the Python packages of scripts/requirements.txt).

use super::*;

#[test]
fn fixtures_regenerate_byte_identical() {
    let needed = "mcap, mcap_protobuf, mcap_ros2, foxglove_schemas_protobuf";
    if !common::python_has(needed) {
        common::skip(
            "fixtures_regenerate_byte_identical",
            &format!(
                "python3 cannot import {needed}; \
                 install with `python3 -m pip install -r scripts/requirements.txt`"
            ),
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (script, log, extra, fixture) in [
        (
            "scripts/make_ros2_fixture.py",
            PROBMOT_LOG,
            None,
            ROS2_FIXTURE,
        ),
        (
            "scripts/make_ros2_fixture.py",
            PROBMOT_V2_LOG,
            Some(["--layout", "2"]),
            ROS2_V2_FIXTURE,
        ),
        (
            "scripts/make_foxglove_fixture.py",
            PROBMOT_LOG,
            None,
            FOXGLOVE_FIXTURE,
        ),
    ] {
        let out: PathBuf = dir.path().join("fixture.mcap");
        let r = Command::new("python3")
            .arg(repo(script))
            .arg(repo(log))
            .args(extra.iter().flatten())
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            r.status.success(),
            "{script}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        assert!(
            std::fs::read(&out).unwrap() == std::fs::read(repo(fixture)).unwrap(),
            "{fixture} differs from a fresh run of {script}"
        );
    }
}
