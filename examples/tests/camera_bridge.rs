//! The shared-memory bridge between two real processes: `camera_sim` publishes a generated
//! drive over iceoryx2 while this test subscribes as the logger does.

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use dash2sim_linux::record::bridge::{CameraInput, CameraSubscriber};
use dash2sim_sim::scenario::sensors::GnssModel;
use dash2sim_sim::scenario::{generate, ScenarioConfig};

fn prefix(name: &str) -> String {
    format!("dash2sim-test/{name}/{}", std::process::id())
}

/// Run `camera_sim` with `args` while `subscriber` hands what arrives to `collect`; its
/// summary line once it exited successfully.
fn run_camera(subscriber: &CameraSubscriber, args: &[&str], mut collect: impl FnMut(CameraInput)) -> String {
    let mut child =
        Command::new(env!("CARGO_BIN_EXE_camera_sim")).args(args).stdout(Stdio::piped()).spawn().expect("camera_sim");
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().expect("child").is_none() && Instant::now() < deadline {
        subscriber.receive(&mut collect).expect("receive");
        std::thread::sleep(Duration::from_millis(2));
    }
    subscriber.receive(&mut collect).expect("receive");
    let output = child.wait_with_output().expect("camera_sim output");
    assert!(output.status.success());
    String::from_utf8_lossy(&output.stdout).trim().to_owned()
}

#[test]
fn every_published_frame_arrives_with_its_pose_and_detections() {
    let prefix = prefix("frames");
    let subscriber = CameraSubscriber::new(&prefix).expect("subscriber");
    let (mut frames, mut poses, mut det3, mut det2) = (Vec::new(), BTreeMap::new(), BTreeMap::new(), BTreeMap::new());
    let mut imu = Vec::new();
    let mut collect = |input: CameraInput| match input {
        CameraInput::Frame { sequence, .. } => frames.push(sequence),
        CameraInput::Vo(_, sequence, session, pose) => {
            poses.insert(sequence, (session, pose));
        }
        CameraInput::Detections3d(t, sequence, d) => {
            det3.insert(sequence, (t, d));
        }
        CameraInput::Detections2d(_, sequence, d) => {
            det2.insert(sequence, d.len());
        }
        CameraInput::Keep(t) => panic!("camera_sim marks nothing to keep, yet a mark came at {t:?}"),
        CameraInput::Imu(t, sample) => imu.push((t, sample)),
    };
    let published = run_camera(
        &subscriber,
        &["--profile", "ideal", "--seconds", "5", "--speedup", "5", "--prefix", &prefix],
        &mut collect,
    );
    assert_eq!(published, "51 frames published");

    let scenario =
        generate(&ScenarioConfig { seed: 1, duration_s: 5.0, gnss: GnssModel::good(), ..ScenarioConfig::default() });
    let expected: Vec<u64> = (1..=51).collect();
    assert_eq!(frames, expected, "every frame sequence arrives, in order");
    assert_eq!(poses.keys().copied().collect::<Vec<_>>(), expected);
    for ((frame, pose), sample) in scenario.frames.iter().zip(&scenario.vo.poses.poses).zip(&scenario.vo.samples) {
        let (session, got) = &poses[&u64::from(frame.index)];
        assert_eq!((got.translation, got.rotation), (pose.translation, pose.rotation), "VO poses arrive exactly");
        assert_eq!(*session, sample.session, "with their VO session");
        let (_, d) = &det3[&u64::from(frame.index)];
        assert_eq!(d.len(), frame.detections_3d.len());
        assert_eq!(det2[&u64::from(frame.index)], frame.detections_2d.len());
    }
    // Capture times are the shared device clock, increasing with the frames.
    let times: Vec<i64> = det3.values().map(|(t, _)| t.micros()).collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]));
    // The IMU's samples up to the last frame, every one, as f32 and spaced as generated
    // (the publisher's clock runs `--speedup` 5 times faster).
    let sent: Vec<_> = scenario.imu.iter().filter(|(t, _)| *t <= 5.0).collect();
    assert_eq!(imu.len(), sent.len(), "every IMU sample arrives");
    for ((t, got), ((t0, _), (t_sent, sample))) in imu.iter().zip(imu.first().iter().cycle().zip(&sent)) {
        assert_eq!(got.gyro, sample.gyro.map(|v| f64::from(v as f32)));
        assert_eq!(got.accel, sample.accel.map(|v| f64::from(v as f32)));
        let spacing = (*t - *t0).as_secs_f64() * 5.0;
        assert!((spacing - (t_sent - sent[0].0)).abs() < 1e-5, "{spacing} vs {}", t_sent - sent[0].0);
    }
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
    use dash2sim_linux::record::bridge::messages::FrameMetaMsg;
    use iceoryx2::prelude::*;
    let prefix = prefix("version");
    let subscriber = CameraSubscriber::new(&prefix).expect("subscriber");
    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let name = ServiceName::new(&format!("{prefix}/frame")).expect("name");
    let service = node
        .service_builder(&name)
        .publish_subscribe::<FrameMetaMsg>()
        .subscriber_max_buffer_size(dash2sim_linux::record::bridge::SUBSCRIBER_BUFFER)
        .enable_safe_overflow(true)
        .open_or_create()
        .expect("service");
    let publisher = service.publisher_builder().create().expect("publisher");
    let message = FrameMetaMsg { version: 2, sequence: 1, ..FrameMetaMsg::default() };
    publisher.loan_uninit().expect("loan").write_payload(message).send().expect("send");
    let error = subscriber.receive(|_| {}).expect_err("refused").to_string();
    assert!(error.contains("layout 2") && error.contains("rebuild the camera process"), "{error}");
}

#[test]
fn a_load_run_publishes_laps_at_30_fps_with_64_objects_and_the_receiver_and_bus_beside_it() {
    let prefix = prefix("load");
    let dir = std::env::temp_dir().join(format!("dash2sim-camera-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let (nmea, can) = (dir.join("gnss.nmea"), dir.join("bus.log"));
    let subscriber = CameraSubscriber::new(&prefix).expect("subscriber");
    let (mut frames, mut detections) = (Vec::new(), Vec::new());
    let mut collect = |input: CameraInput| match input {
        CameraInput::Frame { sequence, .. } => frames.push(sequence),
        CameraInput::Detections3d(_, _, d) => detections.push(d.len()),
        _ => {}
    };
    let (nmea_out, can_out) = (nmea.display().to_string(), can.display().to_string());
    let args =
        ["--seconds", "2", "--fps", "30", "--objects", "64", "--laps", "2", "--speedup", "4", "--prefix", &prefix];
    let args = [&args[..], &["--nmea-out", &nmea_out, "--can-out", &can_out]].concat();
    let published = run_camera(&subscriber, &args, &mut collect);
    assert_eq!(published, "122 frames published");
    assert_eq!(frames, (1..=122).collect::<Vec<u64>>(), "frame numbers go on across laps");
    assert!(detections.iter().all(|&n| n == 64), "64 objects in every frame: {detections:?}");

    // The receiver: 2 laps × 11 fixes × (GGA, RMC), its clock going on in the second lap.
    let text = std::fs::read_to_string(&nmea).expect("nmea");
    let gga: Vec<&str> = text.lines().filter(|l| l.starts_with("$GPGGA")).collect();
    assert_eq!((text.lines().count(), gga.len()), (44, 22));
    let utc = |line: &str| line.split(',').nth(1).expect("time").parse::<f64>().expect("hhmmss");
    assert!(gga.windows(2).all(|w| utc(w[0]) < utc(w[1])), "UTC increases across laps");
    // The bus: 2 laps × 101 CCVS1 frames in candump form, stamps increasing.
    let mut reader =
        dash2sim_can::candump::CandumpReader::new(std::io::BufReader::new(std::fs::File::open(&can).expect("can")));
    let mut stamps = Vec::new();
    while let Some(record) = dash2sim_can::source::FrameSource::next_frame(&mut reader) {
        stamps.push(record.expect("a candump line").time.expect("stamped").micros());
    }
    assert_eq!(stamps.len(), 202);
    assert!(stamps.windows(2).all(|w| w[0] < w[1]));
    let _ = std::fs::remove_dir_all(&dir);
}
