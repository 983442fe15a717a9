//! The codec: every channel's schema, and each encoding against its decoder.

use super::*;

#[test]
fn every_channel_has_a_schema_that_is_an_object_schema() {
    for c in Channel::ALL {
        let s = c.schema();
        assert_eq!(s["type"], "object", "{c:?}");
        assert!(s["properties"].as_object().is_some_and(|p| !p.is_empty()));
        assert_eq!(Channel::from_topic(c.topic()), Some(c));
    }
}

#[test]
fn a_scan_is_a_foxglove_point_cloud_of_its_nearest_returns() {
    let mut m = grop_ipc::ScanMsg {
        seq: 1,
        stamp_ns: 1_500_000_000,
        points_m: [[0.0; 2]; grop_ipc::SCAN_BINS],
    };
    m.set_points([[1.0, 0.0], [0.0, 2.0], [0.0, 2.5]].into_iter());
    let v: Value = serde_json::from_slice(&encode_scan(&m)).unwrap();
    assert_eq!(
        crate::mission_log::foxglove::check(Channel::Scan.schema_name(), &v),
        Ok(())
    );
    assert_eq!(v["timestamp"], json!({"sec": 1, "nsec": 500_000_000}));
    let data = BASE64.decode(v["data"].as_str().unwrap()).unwrap();
    let f = |i: usize| f32::from_le_bytes(data[4 * i..4 * i + 4].try_into().unwrap());
    assert_eq!(data.len(), 2 * 12);
    assert_eq!((f(0), f(1), f(2)), (1.0, 0.0, 0.1));
    assert_eq!((f(3), f(4)), (0.0, 2.0));
}

#[test]
fn inputs_round_trip_exactly() {
    let fix = BasePoseMsg {
        seq: 3,
        stamp_ns: 123_456_789,
        kind: 2,
        reserved: 0,
        x_m: 0.1 + 0.2,
        y_m: -1.0 / 3.0,
        yaw_rad: std::f64::consts::PI,
        sigma_xy_m: 1e-9,
        sigma_yaw_rad: 0.01,
    };
    assert_eq!(decode_base_pose(&encode_base_pose(&fix)).ok(), Some(fix));

    let hb = HeartbeatMsg {
        seq: 9,
        stamp_ns: 5,
        role: 3,
        pid: 0,
        overruns: 2,
    };
    assert_eq!(decode_health(&encode_health(&hb)).ok(), Some(hb));

    for frame in [
        CanFrame::new(CanId::standard(0x500).unwrap(), &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        CanFrame::new(CanId::extended(0x1234_5678).unwrap(), &[]).unwrap(),
    ] {
        assert_eq!(decode_can(&encode_can(&frame)).ok(), Some(frame));
    }
    assert!(decode_can(br#"{"id": 4096, "extended": false, "data": []}"#).is_err());
    assert!(decode_can(br#"{"id": 1, "extended": false, "data": [1,2,3,4,5,6,7,8,9]}"#).is_err());

    let io = ArmIoMsg {
        seq: 1,
        stamp_ns: 2_000_000,
        call: 1,
        outcome: 0,
        status: 0,
        flags: 1,
        robot_mode: 7,
        reserved: 0,
        joints_rad: [0.1, -1.2, 2.3, -0.4, 1.5e-7, 6.0],
        joint_speeds_radps: [0.0; 6],
        flange_pose: [0.3, 0.2, 0.1, 0.0, 3.0, 0.0],
    };
    assert_eq!(decode_arm_io(&encode_arm_io(&io)).ok(), Some(io));
    let mut bad = io;
    bad.call = 99;
    assert!(decode_arm_io(&encode_arm_io(&bad)).is_err());
}

#[test]
fn camera_frames_round_trip_and_bad_ones_are_named() {
    let mut frame: Box<CameraFrameMsg> = CameraFrameMsg::boxed_zeroed();
    let mut header = CameraFrameHeader {
        frame_id: 7,
        stamp_ns: 1_500_000_000,
        width_px: 640,
        height_px: 480,
        pixel_format: 0,
        row_stride_bytes: 640 * 3,
        metres_per_px: 0.0125,
        left_x_m: -0.5,
        top_y_m: 6.0,
    };
    header.set_pixel_format(grop_ipc::PixelFormat::Rgb8);
    let pixels: Vec<u8> = (0..640 * 480 * 3).map(|i| (i * 7 % 251) as u8).collect();
    frame.set_image(header, &pixels).unwrap();
    let data = encode_camera(&frame);
    assert_eq!(camera_frame_id(&data).unwrap(), 7);
    let mut back = CameraFrameMsg::boxed_zeroed();
    decode_camera_into(&data, &mut back).unwrap();
    assert_eq!(back.header, frame.header);
    assert_eq!(back.image().unwrap(), frame.image().unwrap());

    let text = String::from_utf8(data)
        .unwrap()
        .replace("\"rgb8\"", "\"bgr16\"");
    let err = decode_camera_into(text.as_bytes(), &mut back).unwrap_err();
    assert!(err.to_string().contains("bgr16"), "{err}");
}

#[test]
fn the_truth_round_trips_and_a_wrong_one_is_named() {
    let m = TruthMsg {
        seq: 3,
        stamp_ns: 150_000_000,
        x_m: 1.25,
        y_m: -0.1,
        yaw_rad: 3.1,
        speed_mps: 0.3,
        yaw_rate_radps: -0.2,
    };
    assert_eq!(decode_truth(&encode_truth(&m)).unwrap(), m);
    let e = decode_truth(b"{\"seq\": 1}").unwrap_err().to_string();
    assert!(
        e.contains("/world/truth") && e.contains("grop.Truth"),
        "{e}"
    );
}
