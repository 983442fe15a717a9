//! Every service through two iceoryx2 nodes: the publisher's and the subscriber's.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use grop_ipc::{
    ArmSafety, ArmStateMsg, BaseMode, BaseStateMsg, CAMERA_MAX_HEIGHT_PX, CAMERA_MAX_WIDTH_PX,
    CameraFrameHeader, CameraFrameMsg, EventKind, EventMsg, IpcNode, MAX_TASK_STEPS, MessageError,
    NodeError, PixelFormat, TableSide, TaskPlanMsg, TaskStep,
};

const WAIT: Duration = Duration::from_secs(5);

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A namespace no other test uses: pid + counter + test name.
fn unique_namespace(test: &str) -> String {
    format!(
        "test-{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn two_nodes(test: &str) -> (IpcNode, IpcNode) {
    let namespace = unique_namespace(test);
    (
        IpcNode::new(&namespace, "publisher-node").unwrap(),
        IpcNode::new(&namespace, "subscriber-node").unwrap(),
    )
}

#[test]
fn base_state_crosses_nodes_and_ages() {
    let (pub_node, sub_node) = two_nodes("base");
    let publisher = pub_node.publisher::<BaseStateMsg>().unwrap();
    let subscriber = sub_node.subscriber::<BaseStateMsg>().unwrap();
    let reached = publisher
        .publish_with(|state| {
            state.seq = 7;
            state.stamp_ns = 1_000_000_000;
            state.x_m = 1.5;
            state.yaw_rad = 0.25;
            state.speed_mps = 0.4;
            state.link_up = 1;
            state.set_mode(BaseMode::Tractor);
        })
        .unwrap();
    assert_eq!(reached, 1);
    let state = subscriber
        .recv_timeout(WAIT)
        .unwrap()
        .expect("state arrives");
    assert_eq!((state.seq, state.x_m, state.speed_mps), (7, 1.5, 0.4));
    assert_eq!(state.mode(), Ok(BaseMode::Tractor));
    assert_eq!(state.age_ns(1_050_000_000), 50_000_000);
    assert!(!state.is_stale(1_050_000_000, Duration::from_millis(100)));
    assert!(state.is_stale(1_200_000_000, Duration::from_millis(100)));
    assert!(subscriber.try_recv().unwrap().is_none());
}

#[test]
fn latest_keeps_only_the_newest_state() {
    let (pub_node, sub_node) = two_nodes("latest");
    let publisher = pub_node.publisher::<ArmStateMsg>().unwrap();
    let subscriber = sub_node.subscriber::<ArmStateMsg>().unwrap();
    for seq in 1..=5u64 {
        let mut state = ArmStateMsg {
            seq,
            ..zeroed_arm_state()
        };
        state.joints_rad[2] = seq as f64 * 0.1;
        state.set_safety(ArmSafety::Normal);
        publisher.publish(&state).unwrap();
    }
    let newest = subscriber.latest().unwrap().expect("a state");
    assert_eq!(newest.seq, 5);
    assert_eq!(newest.joints_rad[2], 0.5);
    assert_eq!(newest.safety(), Ok(ArmSafety::Normal));
    assert!(subscriber.latest().unwrap().is_none());
}

fn zeroed_arm_state() -> ArmStateMsg {
    ArmStateMsg {
        seq: 0,
        stamp_ns: 0,
        joints_rad: [0.0; 6],
        joint_speeds_radps: [0.0; 6],
        flange_pose: [0.0; 6],
        gripper_opening_m: 0.0,
        safety: 0,
        robot_mode: 0,
        program_running: 0,
        connected: 0,
        object_held: 0,
        reserved: [0; 5],
    }
}

fn camera_header(
    frame_id: u64,
    width_px: u32,
    height_px: u32,
    format: PixelFormat,
) -> CameraFrameHeader {
    let mut header = CameraFrameHeader {
        frame_id,
        stamp_ns: 5,
        width_px,
        height_px,
        pixel_format: 0,
        row_stride_bytes: width_px * format.bytes_per_px() as u32,
        metres_per_px: 0.03125,
        left_x_m: -10.0,
        top_y_m: 11.5,
    };
    header.set_pixel_format(format);
    header
}

#[test]
fn camera_frames_travel_in_place_at_both_sizes() {
    let (pub_node, sub_node) = two_nodes("camera");
    let publisher = pub_node.publisher::<CameraFrameMsg>().unwrap();
    let subscriber = sub_node.subscriber::<CameraFrameMsg>().unwrap();
    for header in [
        camera_header(1, 64, 64, PixelFormat::Mono8),
        camera_header(
            2,
            CAMERA_MAX_WIDTH_PX,
            CAMERA_MAX_HEIGHT_PX,
            PixelFormat::Rgb8,
        ),
    ] {
        let len = header.checked_len().unwrap();
        let pixels: Vec<u8> = (0..len)
            .map(|i| (i % 251) as u8 ^ header.frame_id as u8)
            .collect();
        let mut filled = Ok(());
        publisher
            .publish_with(|frame| filled = frame.set_image(header, &pixels))
            .unwrap();
        filled.unwrap();
        let frame = subscriber
            .recv_timeout(WAIT)
            .unwrap()
            .expect("frame arrives");
        assert_eq!(frame.header, header);
        assert_eq!(frame.image().unwrap(), &pixels[..]);
    }
}

#[test]
fn publish_frame_writes_only_the_image_the_header_describes() {
    let (pub_node, sub_node) = two_nodes("frame");
    let publisher = pub_node.publisher::<CameraFrameMsg>().unwrap();
    let subscriber = sub_node.subscriber::<CameraFrameMsg>().unwrap();
    // Large, then small, then large again: the slots are reused, and each frame reads back as
    // exactly what its header describes, whatever an earlier frame left in the buffer.
    for (header, fill_byte) in [
        (camera_header(1, 640, 480, PixelFormat::Rgb8), 0xAB),
        (camera_header(2, 64, 64, PixelFormat::Mono8), 0x11),
        (camera_header(3, 1280, 960, PixelFormat::Rgb8), 0x5C),
        (camera_header(4, 3, 2, PixelFormat::Mono8), 0x77),
    ] {
        let len = header.checked_len().unwrap();
        let mut seen = None;
        let reached = publisher
            .publish_frame(header, |image| {
                // The image bytes come zeroed, whatever the slot held before.
                seen = Some((image.len(), image.iter().all(|b| *b == 0)));
                for (i, byte) in image.iter_mut().enumerate() {
                    *byte = fill_byte ^ (i % 7) as u8;
                }
            })
            .unwrap();
        assert_eq!(reached, 1);
        assert_eq!(seen, Some((len, true)));
        let frame = subscriber
            .recv_timeout(WAIT)
            .unwrap()
            .expect("frame arrives");
        assert_eq!(frame.header, header);
        let image = frame.image().unwrap();
        assert_eq!(image.len(), len);
        assert!(
            image
                .iter()
                .enumerate()
                .all(|(i, b)| *b == fill_byte ^ (i % 7) as u8)
        );
    }
    // A header that does not check is refused before anything is loaned or sent.
    let bad = camera_header(5, 2000, 10, PixelFormat::Mono8);
    let mut called = false;
    let refused = publisher.publish_frame(bad, |_| called = true);
    assert!(matches!(
        refused,
        Err(grop_ipc::FrameError::Header(
            MessageError::BadImageSize { .. }
        ))
    ));
    assert!(!called);
    assert!(subscriber.try_recv().unwrap().is_none());
}

#[test]
fn bad_image_sizes_are_errors_on_both_ends() {
    let (pub_node, sub_node) = two_nodes("badimage");
    let publisher = pub_node.publisher::<CameraFrameMsg>().unwrap();
    let subscriber = sub_node.subscriber::<CameraFrameMsg>().unwrap();
    let header = camera_header(1, 2000, 10, PixelFormat::Mono8);
    let mut filled = Ok(());
    publisher
        .publish_with(|frame| {
            filled = frame.set_image(header, &[0; 20_000]);
            // A buggy or foreign publisher could still write such a header directly.
            frame.header = header;
        })
        .unwrap();
    assert!(matches!(
        filled,
        Err(MessageError::BadImageSize { width_px: 2000, .. })
    ));
    let frame = subscriber
        .recv_timeout(WAIT)
        .unwrap()
        .expect("frame arrives");
    assert!(matches!(
        frame.image(),
        Err(MessageError::BadImageSize { .. })
    ));
}

fn unload(object_index: u32, side: TableSide, x_m: f64) -> TaskStep {
    TaskStep::unload(
        object_index,
        side,
        [x_m, 6.0, 1.3],
        [x_m, 5.0, std::f64::consts::FRAC_PI_2],
        0.8,
    )
}

#[test]
fn plans_carry_their_steps_and_reject_bad_counts() {
    let (pub_node, sub_node) = two_nodes("plan");
    let publisher = pub_node.publisher::<TaskPlanMsg>().unwrap();
    let subscriber = sub_node.subscriber::<TaskPlanMsg>().unwrap();
    let steps = [
        TaskStep::navigate(-1.5, 5.0, 1.57, 12.5),
        unload(0, TableSide::Near, -1.5),
        unload(2, TableSide::Far, 3.0),
    ];
    let mut set = Ok(());
    publisher
        .publish_with(|plan| {
            plan.plan_id = 3;
            plan.reward = 40.0;
            plan.feasibility = 1.6;
            plan.cost_s = 25.0;
            plan.utility = 40.0 * 1.6 - 25.0;
            set = plan.set_steps(&steps);
        })
        .unwrap();
    set.unwrap();
    let plan = subscriber
        .recv_timeout(WAIT)
        .unwrap()
        .expect("plan arrives");
    assert_eq!(plan.plan_id, 3);
    assert_eq!(plan.steps().unwrap(), &steps[..]);
    assert_eq!(plan.steps().unwrap()[2].side(), Ok(TableSide::Far));

    // A corrupted count or side from another process is an error, not a panic.
    publisher
        .publish_with(|plan| {
            plan.step_count = 999;
            plan.steps[0].side = 5;
        })
        .unwrap();
    let bad = subscriber
        .recv_timeout(WAIT)
        .unwrap()
        .expect("plan arrives");
    assert!(matches!(
        bad.steps(),
        Err(MessageError::CountTooLarge { count: 999, .. })
    ));
    assert!(bad.steps[0].side().is_err());
    let mut too_long = Ok(());
    publisher
        .publish_with(|plan| {
            too_long = plan.set_steps(&[unload(0, TableSide::Near, 0.0); MAX_TASK_STEPS + 1]);
        })
        .unwrap();
    assert!(too_long.is_err());
}

#[test]
fn a_late_subscriber_gets_the_current_plan() {
    let (pub_node, sub_node) = two_nodes("history");
    let mut publisher = pub_node.publisher::<TaskPlanMsg>().unwrap();
    publisher.publish_with(|plan| plan.plan_id = 1).unwrap();
    publisher.publish_with(|plan| plan.plan_id = 2).unwrap();
    let subscriber = sub_node.subscriber::<TaskPlanMsg>().unwrap();
    // The planner's cycle hands the history to subscribers that joined meanwhile.
    publisher.serve_late_subscribers().unwrap();
    let plan = subscriber.recv_timeout(WAIT).unwrap().expect("history");
    assert_eq!(plan.plan_id, 2, "only the newest plan is history");
    assert!(subscriber.try_recv().unwrap().is_none());
}

#[test]
fn events_carry_text_and_are_not_replayed_to_late_joiners() {
    let (pub_node, sub_node) = two_nodes("events");
    let publisher = pub_node.publisher::<EventMsg>().unwrap();
    publisher
        .publish(&EventMsg::new(
            EventKind::PlanStarted,
            1,
            "before the subscriber",
        ))
        .unwrap();
    let subscriber = sub_node.subscriber::<EventMsg>().unwrap();
    let mut failed = EventMsg::new(EventKind::UnloadFailed, 2, "arm out of reach at step 1: é");
    failed.plan_id = 9;
    failed.step_index = 1;
    publisher.publish(&failed).unwrap();
    let event = subscriber.recv_timeout(WAIT).unwrap().expect("event");
    assert_eq!(event.kind(), Ok(EventKind::UnloadFailed));
    assert_eq!(event.detail(), Ok("arm out of reach at step 1: é"));
    assert_eq!((event.plan_id, event.step_index), (9, 1));
    assert!(subscriber.try_recv().unwrap().is_none());

    let long = "x".repeat(111) + "é";
    assert_eq!(
        EventMsg::new(EventKind::LinkLost, 0, &long)
            .detail()
            .unwrap(),
        "x".repeat(111)
    );
    let mut garbage = EventMsg::new(EventKind::LinkLost, 0, "");
    garbage.kind = 77;
    garbage.detail_len = 500;
    assert!(garbage.kind().is_err());
    assert!(garbage.detail().is_err());
    garbage.detail_len = 1;
    garbage.detail[0] = 0xFF;
    assert_eq!(garbage.detail(), Err(MessageError::DetailNotUtf8));
}

#[test]
fn namespaces_isolate_services() {
    let a = IpcNode::new(&unique_namespace("ns-a"), "a").unwrap();
    let b = IpcNode::new(&unique_namespace("ns-b"), "b").unwrap();
    let publisher = a.publisher::<BaseStateMsg>().unwrap();
    let subscriber = b.subscriber::<BaseStateMsg>().unwrap();
    assert_eq!(publisher.publish_with(|s| s.seq = 1).unwrap(), 0);
    assert!(
        subscriber
            .recv_timeout(Duration::from_millis(50))
            .unwrap()
            .is_none()
    );
    assert!(publisher.service().ends_with("/base/state"));
}

#[test]
fn invalid_namespaces_are_refused() {
    for namespace in [
        "",
        "/robot",
        "robot/",
        "a//b",
        "with space",
        &"n".repeat(101),
    ] {
        assert!(
            matches!(
                IpcNode::new(namespace, "node"),
                Err(NodeError::InvalidNamespace { .. })
            ),
            "{namespace:?}"
        );
    }
    assert!(IpcNode::new("robot/arm-1.sim_2", "node").is_ok());
}

#[test]
fn a_blocked_subscriber_wakes_for_a_message_from_another_thread() {
    let namespace = unique_namespace("wake");
    let sub_node = IpcNode::new(&namespace, "sub").unwrap();
    let subscriber = sub_node.subscriber::<EventMsg>().unwrap();
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let publisher_thread = std::thread::spawn(move || {
        let node = IpcNode::new(&namespace, "pub").unwrap();
        let publisher = node.publisher::<EventMsg>().unwrap();
        std::thread::sleep(Duration::from_millis(30));
        publisher
            .publish(&EventMsg::new(EventKind::StaleInput, 3, "base state stale"))
            .unwrap();
        // A subscriber maps a publisher's memory on its next receive: keep the publisher alive
        // until then (a publisher that is already gone takes unread messages with it).
        let _ = done_rx.recv_timeout(WAIT);
    });
    let event = subscriber.recv_timeout(WAIT).unwrap().expect("woken");
    assert_eq!(event.kind(), Ok(EventKind::StaleInput));
    drop(event);
    done_tx.send(()).unwrap();
    publisher_thread.join().unwrap();
}

/// Role of the child process in `services_work_across_two_processes`; does nothing when run as
/// an ordinary test.
#[test]
fn child_process_role() {
    let Ok(namespace) = std::env::var("GROP_IPC_TEST_CHILD_NAMESPACE") else {
        return;
    };
    let node = IpcNode::new(&namespace, "child").unwrap();
    let done = node.subscriber::<EventMsg>().unwrap();
    let frames = node.publisher::<CameraFrameMsg>().unwrap();
    let states = node.publisher::<BaseStateMsg>().unwrap();
    let header = camera_header(42, 64, 64, PixelFormat::Mono8);
    let pixels: Vec<u8> = (0..64 * 64).map(|i| (i * 7 % 256) as u8).collect();
    frames
        .publish_with(|frame| frame.set_image(header, &pixels).unwrap())
        .unwrap();
    states
        .publish_with(|state| {
            state.seq = 11;
            state.set_mode(BaseMode::Standby);
        })
        .unwrap();
    // Stay until the parent has read everything (it maps our memory on its receive).
    let event = done.recv_timeout(Duration::from_secs(20)).unwrap();
    assert_eq!(event.map(|e| e.kind()), Some(Ok(EventKind::PlanFinished)));
}

#[test]
fn services_work_across_two_processes() {
    let namespace = unique_namespace("xproc");
    let node = IpcNode::new(&namespace, "parent").unwrap();
    let frames = node.subscriber::<CameraFrameMsg>().unwrap();
    let states = node.subscriber::<BaseStateMsg>().unwrap();
    let done = node.publisher::<EventMsg>().unwrap();
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_process_role", "--test-threads", "1"])
        .env("GROP_IPC_TEST_CHILD_NAMESPACE", &namespace)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let frame = frames
        .recv_timeout(WAIT)
        .unwrap()
        .expect("frame from the child");
    assert_eq!(frame.header.frame_id, 42);
    let expected: Vec<u8> = (0..64 * 64).map(|i| (i * 7 % 256) as u8).collect();
    assert_eq!(frame.image().unwrap(), &expected[..]);
    let state = states
        .recv_timeout(WAIT)
        .unwrap()
        .expect("state from the child");
    assert_eq!((state.seq, state.mode()), (11, Ok(BaseMode::Standby)));
    drop((frame, state));
    // The child may not have joined `events` when we first publish: repeat until it leaves.
    let status = loop {
        done.publish(&EventMsg::new(EventKind::PlanFinished, 2, "parent done"))
            .unwrap();
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "child exited with {status}");
}
