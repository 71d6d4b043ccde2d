//! The C ABI called as C calls it: bad arguments are refused with their status code and a
//! description, never a crash; what is published arrives at the logger's subscriber; the
//! layout report names the types iceoryx2 checks.

use std::ffi::{CStr, CString};

use dash2sim_camera::*;
use dash2sim_linux::record::bridge::messages::{self, Detection3dItem, FrameMetaMsg, VoPoseMsg};
use dash2sim_linux::record::bridge::{CameraInput, CameraSubscriber};
use iceoryx2::prelude::ZeroCopySend;

fn last_error() -> String {
    // SAFETY: d2s_last_error returns a NUL-terminated string valid until the next call.
    unsafe { CStr::from_ptr(d2s_last_error()) }.to_string_lossy().into_owned()
}

fn prefix(name: &str) -> CString {
    CString::new(format!("dash2sim-test/abi/{name}/{}", std::process::id())).expect("prefix")
}

#[test]
fn null_and_out_of_range_arguments_are_refused_with_a_code_and_a_reason() {
    let mut status = 0;
    // SAFETY: the arguments are what the header allows: null is refused, not read.
    let publisher = unsafe { d2s_publisher_open(std::ptr::null(), false, &mut status) };
    assert!(publisher.is_null());
    assert_eq!(status, D2S_ERR_NULL);
    assert_eq!(last_error(), "d2s_publisher_open: the prefix is null");

    let null = std::ptr::null_mut();
    // SAFETY: a null publisher is allowed and refused.
    unsafe {
        assert_eq!(d2s_publish_frame(null, 1, 0, 0), D2S_ERR_NULL);
        assert_eq!(d2s_publish_detections3d(null, 1, 0, std::ptr::null(), 0), D2S_ERR_NULL);
        assert_eq!(d2s_image_send(null, 1, 0, 0), D2S_ERR_NULL);
        assert_eq!(d2s_mark_keep(null, 0), D2S_ERR_NULL);
        assert!(d2s_image_loan(null, 10, &mut status).is_null());
        d2s_publisher_close(null);
    }
    assert_eq!(status, D2S_ERR_NULL);

    let name = prefix("arguments");
    // SAFETY: a NUL-terminated prefix and a status to write.
    let publisher = unsafe { d2s_publisher_open(name.as_ptr(), false, &mut status) };
    assert!(!publisher.is_null(), "{}", last_error());
    assert_eq!((status, last_error().as_str()), (D2S_OK, ""));
    let boxes = [Detection3dItem::default(); 65];
    let position = [0.0; 3];
    let not_finite = [f64::NAN; 9];
    // SAFETY: `publisher` is open; the arrays are as long as the calls say.
    unsafe {
        assert_eq!(d2s_publish_detections3d(publisher, 1, 0, boxes.as_ptr(), 65), D2S_ERR_RANGE);
        assert!(last_error().contains("65 3D detections: at most 64"), "{}", last_error());
        assert_eq!(d2s_publish_detections3d(publisher, 1, 0, std::ptr::null(), 3), D2S_ERR_NULL);
        assert_eq!(d2s_publish_detections3d(publisher, 1, 0, std::ptr::null(), 0), D2S_OK);
        assert_eq!(d2s_publish_vo(publisher, 1, 0, 0, position.as_ptr(), std::ptr::null()), D2S_ERR_NULL);
        assert_eq!(d2s_publish_vo(publisher, 1, 0, 0, position.as_ptr(), not_finite.as_ptr()), D2S_ERR_RANGE);
        assert_eq!(d2s_image_send(publisher, 1, 0, 0), D2S_ERR_NO_LOAN);
        // Without the image service there is nothing to loan.
        assert!(d2s_image_loan(publisher, 10, &mut status).is_null());
        assert_eq!(status, D2S_ERR_SHARED_MEMORY);
        assert!(last_error().contains("without the image service"), "{}", last_error());
        d2s_publisher_close(publisher);
    }

    let unknown = CString::new("unicorn").expect("name");
    let cone = CString::new("cone").expect("name");
    // SAFETY: NUL-terminated names, or null.
    unsafe {
        assert_eq!(d2s_class_id(cone.as_ptr()), 2);
        assert_eq!(d2s_class_id(unknown.as_ptr()), -1);
        assert_eq!(d2s_class_id(std::ptr::null()), -1);
    }
}

#[test]
fn a_logger_is_listening_once_it_has_subscribed_and_not_after() {
    let name = prefix("listening");
    // SAFETY: a NUL-terminated prefix, or null (refused).
    unsafe {
        assert_eq!(d2s_logger_listening(std::ptr::null()), D2S_ERR_NULL);
        assert_eq!(last_error(), "d2s_logger_listening: the prefix is null");
        assert_eq!(d2s_logger_listening(name.as_ptr()), 0, "{}", last_error());
        let logger = CameraSubscriber::new(name.to_str().expect("utf-8")).expect("subscriber");
        assert_eq!(d2s_logger_listening(name.as_ptr()), 1, "{}", last_error());
        drop(logger);
        assert_eq!(d2s_logger_listening(name.as_ptr()), 0, "{}", last_error());
    }
}

#[test]
fn what_c_publishes_arrives_at_the_logger_with_its_image() {
    let name = prefix("arrives");
    let subscriber = CameraSubscriber::new(name.to_str().expect("utf-8")).expect("subscriber");
    let mut status = 0;
    // SAFETY: a NUL-terminated prefix and a status to write.
    let publisher = unsafe { d2s_publisher_open(name.as_ptr(), true, &mut status) };
    assert!(!publisher.is_null(), "{}", last_error());
    let q = [0.9, 0.1, -0.2, 0.3];
    let mut rotation = [0.0; 9];
    let boxes =
        [Detection3dItem { class: 2, score: 0.5, bbox: [10.0, 1.0, 0.3, 0.0, 0.4, 0.4, 0.7], ..Default::default() }];
    // SAFETY: `publisher` is open; the arrays are as long as the calls say; the loaned
    // memory is written within its length before it is sent.
    unsafe {
        d2s_rotation_from_quaternion(q.as_ptr(), rotation.as_mut_ptr());
        let image = d2s_image_loan(publisher, 1000, &mut status);
        assert!(!image.is_null(), "{}", last_error());
        assert_eq!(d2s_image_loan(publisher, 10, &mut status), std::ptr::null_mut(), "one loan at a time");
        std::slice::from_raw_parts_mut(image, 1000).fill(7);
        assert_eq!(d2s_image_send(publisher, 5, 1_000_000, 8000), D2S_OK);
        assert_eq!(d2s_publish_vo(publisher, 5, 1_000_000, 2, [1.0, 2.0, 3.0].as_ptr(), rotation.as_ptr()), D2S_OK);
        assert_eq!(d2s_publish_detections3d(publisher, 5, 1_000_000, boxes.as_ptr(), 1), D2S_OK);
        assert_eq!(d2s_mark_keep(publisher, 1_050_000), D2S_OK);
        let (gyro, accel) = ([0.01f32, -0.02, 0.3], [0.5f32, -0.25, 9.81]);
        assert_eq!(d2s_publish_imu(publisher, 1_010_000, gyro.as_ptr(), accel.as_ptr()), D2S_OK);
        assert_eq!(d2s_publish_imu(publisher, 1_020_000, gyro.as_ptr(), std::ptr::null()), D2S_ERR_NULL);
        let nan = [f32::NAN, 0.0, 0.0];
        assert_eq!(d2s_publish_imu(publisher, 1_020_000, nan.as_ptr(), accel.as_ptr()), D2S_ERR_RANGE);
        assert!(last_error().contains("not finite"), "{}", last_error());
        // The next frame says how many IMU samples went before it (one: the refused ones
        // were not sent).
        assert_eq!(d2s_publish_frame(publisher, 6, 1_100_000, 8000), D2S_OK);
    }
    let mut inputs = Vec::new();
    subscriber.receive(|input| inputs.push(input)).expect("receive");
    // SAFETY: open, and not used again.
    unsafe { d2s_publisher_close(publisher) };
    let expected = dash2sim_core::sim3::Pose::from_quaternion_wxyz(q, [1.0, 2.0, 3.0].into());
    let t = dash2sim_core::time::Timestamp::from_micros(1_000_000);
    assert_eq!(inputs.len(), 6, "{inputs:?}");
    let imu = dash2sim_core::imu::ImuSample {
        gyro: [0.01f32, -0.02, 0.3].map(f64::from),
        accel: [0.5f32, -0.25, 9.81].map(f64::from),
    };
    // `receive` drains the frame service first (`CameraSubscriber::receive`).
    assert_eq!(
        inputs[0],
        CameraInput::Frame { sequence: 5, t, exposure_us: 8000, image_bytes: 1000, imu_published: 0 }
    );
    let t6 = dash2sim_core::time::Timestamp::from_micros(1_100_000);
    assert_eq!(
        inputs[1],
        CameraInput::Frame { sequence: 6, t: t6, exposure_us: 8000, image_bytes: 0, imu_published: 1 }
    );
    assert_eq!(inputs[2], CameraInput::Imu(dash2sim_core::time::Timestamp::from_micros(1_010_000), imu));
    assert_eq!(inputs[5], CameraInput::Keep(dash2sim_core::time::Timestamp::from_micros(1_050_000)));
    assert_eq!(inputs[3], CameraInput::Vo(t, 5, 2, expected), "the rotation bit for bit as record reads it");
    let CameraInput::Detections3d(_, 5, ref d) = inputs[4] else { panic!("{:?}", inputs[4]) };
    assert_eq!((d.len(), d[0].class, d[0].bbox.x), (1, 2, 10.0));
}

#[test]
fn the_layout_report_names_the_types_iceoryx2_checks() {
    // SAFETY: the derive's type names are plain strings.
    let derived = unsafe { [FrameMetaMsg::type_name(), VoPoseMsg::type_name(), Detection3dItem::type_name()] };
    let reported: Vec<&str> = messages::layouts().iter().map(|l| l.type_name).collect();
    assert_eq!(&reported[..3], &derived[..]);
    // SAFETY: a static NUL-terminated string.
    let json = unsafe { CStr::from_ptr(d2s_layout_json()) }.to_str().expect("utf-8");
    let json: serde_json::Value = serde_json::from_str(json).expect("json");
    assert_eq!(json["layout_version"], D2S_LAYOUT_VERSION);
    assert_eq!(json["messages"][0]["type_name"], "dash2sim::FrameMetaMsg");
    assert_eq!(json["messages"][0]["size"], size_of::<FrameMetaMsg>());
}
