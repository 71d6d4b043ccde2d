//! The shared-memory bridge between two real processes: `camera_sim` publishes a generated
//! drive over iceoryx2 while this test subscribes as the logger does.

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use dash2sim_linux::bridge::{CameraInput, CameraSubscriber};
use dash2sim_linux::scenario::sensors::GnssModel;
use dash2sim_linux::scenario::{generate, ScenarioConfig};

fn prefix(name: &str) -> String {
    format!("dash2sim-test/{name}/{}", std::process::id())
}

#[test]
fn every_published_frame_arrives_with_its_pose_and_detections() {
    let prefix = prefix("frames");
    let subscriber = CameraSubscriber::new(&prefix).expect("subscriber");
    let mut child = Command::new(env!("CARGO_BIN_EXE_camera_sim"))
        .args(["--seconds", "5", "--speedup", "5", "--prefix", &prefix])
        .stdout(Stdio::piped())
        .spawn()
        .expect("camera_sim");
    let (mut frames, mut poses, mut det3, mut det2) = (Vec::new(), BTreeMap::new(), BTreeMap::new(), BTreeMap::new());
    let mut collect = |input: CameraInput| match input {
        CameraInput::Frame { sequence, .. } => frames.push(sequence),
        CameraInput::Vo(_, sequence, pose) => {
            poses.insert(sequence, pose);
        }
        CameraInput::Detections3d(t, sequence, d) => {
            det3.insert(sequence, (t, d));
        }
        CameraInput::Detections2d(_, sequence, d) => {
            det2.insert(sequence, d.len());
        }
    };
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().expect("child").is_none() && Instant::now() < deadline {
        subscriber.receive(&mut collect).expect("receive");
        std::thread::sleep(Duration::from_millis(2));
    }
    subscriber.receive(&mut collect).expect("receive");
    let output = child.wait_with_output().expect("camera_sim output");
    assert!(output.status.success());
    assert_eq!(String::from_utf8_lossy(&output.stdout).trim(), "51 frames published");

    let scenario =
        generate(&ScenarioConfig { seed: 1, duration_s: 5.0, gnss: GnssModel::good(), ..ScenarioConfig::default() });
    let expected: Vec<u64> = (1..=51).collect();
    assert_eq!(frames, expected, "every frame sequence arrives, in order");
    assert_eq!(poses.keys().copied().collect::<Vec<_>>(), expected);
    for (frame, pose) in scenario.frames.iter().zip(&scenario.vo.poses) {
        let got = &poses[&u64::from(frame.index)];
        assert_eq!((got.translation, got.rotation), (pose.translation, pose.rotation), "VO poses arrive exactly");
        let (_, d) = &det3[&u64::from(frame.index)];
        assert_eq!(d.len(), frame.detections_3d.len());
        assert_eq!(det2[&u64::from(frame.index)], frame.detections_2d.len());
    }
    // Capture times are the shared device clock, increasing with the frames.
    let times: Vec<i64> = det3.values().map(|(t, _)| t.micros()).collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]));
}

#[test]
fn a_publisher_of_another_layout_is_refused_with_a_message() {
    use iceoryx2::prelude::*;
    let prefix = prefix("layout");
    // Another program owns `<prefix>/frame` with another payload type.
    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let name = ServiceName::new(&format!("{prefix}/frame")).expect("name");
    let _foreign = node.service_builder(&name).publish_subscribe::<u64>().open_or_create().expect("service");
    let error = CameraSubscriber::new(&prefix).expect_err("refused").to_string();
    assert!(error.contains("another dash2sim message layout"), "{error}");
}

#[test]
fn a_message_of_another_layout_version_is_refused_with_a_message() {
    use dash2sim_linux::bridge::messages::FrameMetaMsg;
    use iceoryx2::prelude::*;
    let prefix = prefix("version");
    let subscriber = CameraSubscriber::new(&prefix).expect("subscriber");
    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let name = ServiceName::new(&format!("{prefix}/frame")).expect("name");
    let service = node
        .service_builder(&name)
        .publish_subscribe::<FrameMetaMsg>()
        .subscriber_max_buffer_size(dash2sim_linux::bridge::SUBSCRIBER_BUFFER)
        .enable_safe_overflow(true)
        .open_or_create()
        .expect("service");
    let publisher = service.publisher_builder().create().expect("publisher");
    let message = FrameMetaMsg { version: 2, sequence: 1, ..FrameMetaMsg::default() };
    publisher.loan_uninit().expect("loan").write_payload(message).send().expect("send");
    let error = subscriber.receive(|_| {}).expect_err("refused").to_string();
    assert!(error.contains("layout 2") && error.contains("rebuild the camera process"), "{error}");
}
