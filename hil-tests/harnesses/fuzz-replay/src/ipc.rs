//! IPC messages (`runtime/libraries/ipc`): every message type's validating accessors over bytes another
//! process could have left in shared memory, and the camera frame header with the view cut the
//! planner node makes from it (`world::camera::cut_view`).
#![allow(
    unsafe_code,
    reason = "the fuzz replay builds wire messages from arbitrary bytes (AnyBitPattern on plain-old-data messages)"
)]

use std::alloc::{Layout, alloc_zeroed};
use std::cell::RefCell;

use grop_ipc::{
    ArmIoMsg, ArmStateMsg, BasePoseMsg, BaseStateMsg, CAMERA_MAX_BYTES, CameraFrameHeader,
    CameraFrameMsg, EVENT_DETAIL_CAPACITY, EventMsg, HeartbeatMsg, HeatmapsMsg, LoadRequestMsg,
    MAX_HEATMAPS, MAX_TASK_STEPS, ReplanRequestMsg, TaskPlanMsg, TaskStep, Topic,
};
use world::camera::cut_view;
use world::view::{CROP_COLS, CROP_ROWS, Side};

/// Message types for which every bit pattern is a valid value.
///
/// # Safety
///
/// Implement only for `#[repr(C)]` types whose fields are all integers, floats, or arrays and
/// structs of those (no `bool`, `char`, enum, reference or pointer). Checked by hand for each
/// type below against `runtime/libraries/ipc/src/{messages,mission,camera}.rs`: enums travel as `u32`/`i32`
/// and are read through checked accessors. They also have no padding (explicit `reserved`
/// fields; the ipc crate's `wire_sizes_are_fixed` tests pin the sizes), so their bytes can be
/// read back too ([`bytes_of`]).
unsafe trait AnyBitPattern: Sized {}

// SAFETY: see the trait; each is integers/floats/byte arrays (and structs of those) only.
unsafe impl AnyBitPattern for BaseStateMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for ArmStateMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for EventMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for TaskPlanMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for ReplanRequestMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for HeatmapsMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for BasePoseMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for HeartbeatMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for CameraFrameMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for CameraFrameHeader {}
// SAFETY: as above.
unsafe impl AnyBitPattern for ArmIoMsg {}
// SAFETY: as above.
unsafe impl AnyBitPattern for TaskStep {}
// SAFETY: as above.
unsafe impl AnyBitPattern for LoadRequestMsg {}

/// The bytes of a value (equality of values with NaNs in them is equality of their bytes).
fn raw<T: AnyBitPattern>(value: &T) -> &[u8] {
    raw_slice(std::slice::from_ref(value))
}

/// The bytes of a slice of values.
fn raw_slice<T: AnyBitPattern>(values: &[T]) -> &[u8] {
    // SAFETY: `T` has no padding (`AnyBitPattern`), so every byte of the slice is initialised;
    // the byte slice borrows `values` for its whole life.
    unsafe { std::slice::from_raw_parts(values.as_ptr().cast::<u8>(), size_of_val(values)) }
}

/// Scratch memory for reading a message in place: 8-byte words (every message's alignment is
/// at most 8), as large as the largest message, allocated once per thread. Only the bytes the
/// last input wrote are zeroed again, so a 3.5 MiB camera message costs what its input costs.
struct Scratch {
    words: Vec<u64>,
    dirty: usize,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = const { RefCell::new(Scratch { words: Vec::new(), dirty: 0 }) };
}

/// Runs `f` on a `T` whose first bytes are `bytes` (at most `size_of::<T>()` of them) and whose
/// other bytes are zero, as if read from shared memory.
fn with_message<T: AnyBitPattern, R>(bytes: &[u8], f: impl FnOnce(&T) -> R) -> R {
    assert!(align_of::<T>() <= align_of::<u64>());
    let size = size_of::<T>();
    let n = bytes.len().min(size);
    let ptr = SCRATCH.with_borrow_mut(|s| {
        let words = size.div_ceil(8);
        if s.words.len() < words {
            s.words.resize(words, 0);
        }
        // SAFETY: the words are initialised memory of at least `size` bytes.
        let buf = unsafe {
            std::slice::from_raw_parts_mut(s.words.as_mut_ptr().cast::<u8>(), s.words.len() * 8)
        };
        buf[n..s.dirty.max(n)].fill(0);
        buf[..n].copy_from_slice(&bytes[..n]);
        s.dirty = n;
        s.words.as_ptr().cast::<T>()
    });
    // SAFETY: `ptr` is aligned (u64 words, align_of::<T>() <= 8), points to `size` initialised
    // bytes, all of which form a valid `T` (`AnyBitPattern`). The scratch is only written at
    // the next call, which cannot happen while `f` holds the reference (targets do not nest).
    f(unsafe { &*ptr })
}

/// A zeroed, properly aligned `T` on the heap (the large frames do not fit a fuzzer's stack)
/// with the first bytes of `T` replaced by `bytes` (at most `size_of::<T>()` of them are used).
fn message_from_bytes<T: AnyBitPattern>(bytes: &[u8]) -> Box<T> {
    let layout = Layout::new::<T>();
    assert!(layout.size() > 0);
    // SAFETY: the layout has a non-zero size. All-zero bytes, and then any bytes copied over
    // them, are a valid `T` (`AnyBitPattern`). The allocation is made with `T`'s layout, so the
    // Box may own and free it; the copy stays inside the allocation.
    unsafe {
        let ptr = alloc_zeroed(layout);
        if ptr.is_null() {
            std::alloc::handle_alloc_error(layout);
        }
        let n = bytes.len().min(layout.size());
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr, n);
        Box::from_raw(ptr.cast::<T>())
    }
}

fn zeroed<T: AnyBitPattern>() -> Box<T> {
    message_from_bytes(&[])
}

/// The bytes of a message, as a publisher leaves them in shared memory.
fn bytes_of<T: AnyBitPattern>(msg: &T) -> Vec<u8> {
    // SAFETY: `T` has no padding (`AnyBitPattern`), so all its `size_of::<T>()` bytes are
    // initialised; the slice borrows `msg` and is copied out before the borrow ends.
    unsafe { std::slice::from_raw_parts((msg as *const T).cast::<u8>(), size_of::<T>()) }.to_vec()
}

/// A valid message of the type [`ipc_messages`] selects with `which` (0..=10), as bytes; the
/// large ones cut after their meaningful part (the rest reads as zeros).
pub(crate) fn bytes_of_message(which: u8) -> Vec<u8> {
    use grop_ipc::{
        ArmSafety, BaseMode, EventKind, PixelFormat as IpcFormat, PoseFixKind, ProcessRole,
        ReplanReason, TableSide, TaskStep,
    };
    let mut bytes = match which % MESSAGE_TYPES {
        0 => {
            let mut msg = zeroed::<BaseStateMsg>();
            msg.seq = 9;
            msg.speed_mps = 0.4;
            msg.set_mode(BaseMode::Tractor);
            bytes_of(&*msg)
        }
        1 => {
            let mut msg = zeroed::<ArmStateMsg>();
            msg.joints_rad = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0];
            msg.set_safety(ArmSafety::ProtectiveStop);
            bytes_of(&*msg)
        }
        2 => bytes_of(&EventMsg::new(
            EventKind::UnloadFailed,
            7,
            "object 2: unreachable ✓",
        )),
        3 => {
            let mut msg = zeroed::<TaskPlanMsg>();
            msg.object_count = 1;
            let steps = [
                TaskStep::navigate(0.0, 1.05, -1.57, 2.5),
                TaskStep::load(1, 0.0, 1.05),
                TaskStep::unload(0, TableSide::Near, [1.0, 6.0, 1.3], [1.0, 5.2, 1.57], 0.8),
            ];
            let _ = msg.set_steps(&steps);
            let mut b = bytes_of(&*msg);
            b.truncate(80 + 88 * 4);
            b
        }
        4 => {
            let mut msg = zeroed::<ReplanRequestMsg>();
            msg.request_id = 2;
            msg.set_reason(ReplanReason::UnloadFailed);
            msg.failed_side = -1;
            msg.remaining_mask = 0b101;
            bytes_of(&*msg)
        }
        5 => {
            let mut msg = zeroed::<HeatmapsMsg>();
            msg.count = 2;
            msg.locations[0].side = 1;
            msg.locations[0].values[0] = 0.5;
            let mut b = bytes_of(&*msg);
            b.truncate(24 + 64);
            b
        }
        6 => bytes_of(&BasePoseMsg::fix(
            4,
            5,
            PoseFixKind::TableRelative,
            [1.0, 5.2, 1.57],
            0.01,
            0.005,
        )),
        7 => {
            let mut msg = zeroed::<HeartbeatMsg>();
            msg.pid = 1234;
            msg.set_role(ProcessRole::Executive);
            bytes_of(&*msg)
        }
        10 => bytes_of(&LoadRequestMsg::new(3, 9, 2, 4, 0b1010, [0.0, 1.05])),
        9 => {
            let mut msg = zeroed::<ArmIoMsg>();
            msg.seq = 12;
            msg.call = grop_ipc::ArmCall::StartMoveJoints as u32;
            msg.outcome = grop_ipc::ArmOutcome::Ok as u32;
            msg.joints_rad = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0];
            bytes_of(&*msg)
        }
        _ => {
            let mut msg = zeroed::<CameraFrameMsg>();
            let mut header = *zeroed::<CameraFrameHeader>();
            header.width_px = 4;
            header.height_px = 2;
            header.set_pixel_format(IpcFormat::Rgb8);
            header.row_stride_bytes = 12;
            header.metres_per_px = 1.0;
            let pixels: Vec<u8> = (0..24u8).collect();
            let _ = msg.set_image(header, &pixels);
            let mut b = bytes_of(&*msg);
            b.truncate(56 + 24);
            b
        }
    };
    bytes.shrink_to_fit();
    bytes
}

/// Message types [`ipc_messages`] tells apart by its first byte.
pub(crate) const MESSAGE_TYPES: u8 = 11;

/// First byte: which message type (11 of them); the rest: its bytes (zero-filled to the type's size). Every
/// checked accessor either errors or returns what the raw fields say, within the capacities;
/// values that check, written back through the setters, read back the same.
pub fn ipc_messages(data: &[u8]) {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    match which % MESSAGE_TYPES {
        0 => base_state(bytes),
        1 => arm_state(bytes),
        2 => event(bytes),
        3 => task_plan(bytes),
        4 => replan_request(bytes),
        5 => heatmaps(bytes),
        6 => base_pose(bytes),
        7 => heartbeat(bytes),
        8 => camera_message(bytes),
        9 => arm_io(bytes),
        _ => load_request(bytes),
    }
}

fn load_request(bytes: &[u8]) {
    with_message::<LoadRequestMsg, _>(bytes, check_load_request);
}

fn check_load_request(msg: &LoadRequestMsg) {
    let _ = msg.stamp_ns();
    match msg.station() {
        Ok(station) => {
            assert!(station.iter().all(|v| v.is_finite()));
            let again = LoadRequestMsg::new(
                msg.request_id,
                msg.stamp_ns,
                msg.plan_id,
                msg.step_index,
                msg.object_mask,
                station,
            );
            assert_eq!(again.station(), Ok(station));
            assert_eq!(again.object_mask, msg.object_mask);
        }
        Err(e) => {
            let _ = e.to_string();
            assert!(msg.station_m.iter().any(|v| !v.is_finite()));
        }
    }
}

fn base_state(bytes: &[u8]) {
    with_message::<BaseStateMsg, _>(bytes, check_base_state);
}

fn check_base_state(msg: &BaseStateMsg) {
    let _ = msg.stamp_ns();
    if let Ok(mode) = msg.mode() {
        let mut copy = *msg;
        copy.set_mode(mode);
        assert_eq!(
            raw(&copy),
            raw(msg),
            "the mode's wire value is the one read"
        );
    }
}

fn arm_state(bytes: &[u8]) {
    with_message::<ArmStateMsg, _>(bytes, check_arm_state);
}

fn check_arm_state(msg: &ArmStateMsg) {
    let _ = msg.stamp_ns();
    if let Ok(safety) = msg.safety() {
        let mut copy = *msg;
        copy.set_safety(safety);
        assert_eq!(copy.safety, msg.safety);
    }
}

fn event(bytes: &[u8]) {
    with_message::<EventMsg, _>(bytes, check_event);
    // Any text, cut to the capacity at a character boundary, reads back as its prefix.
    let text = String::from_utf8_lossy(bytes);
    let made = EventMsg::new(grop_ipc::EventKind::LinkLost, 0, &text);
    match made.detail() {
        Ok(detail) => assert!(text.starts_with(detail) && detail.len() <= EVENT_DETAIL_CAPACITY),
        Err(e) => panic!("EventMsg::new made an unreadable detail: {e}"),
    }
}

fn check_event(msg: &EventMsg) {
    let _ = msg.stamp_ns();
    let kind = msg.kind();
    match msg.detail() {
        Ok(detail) => {
            assert_eq!(detail.len(), msg.detail_len as usize);
            assert!(detail.len() <= EVENT_DETAIL_CAPACITY);
            if let Ok(kind) = kind {
                let again = EventMsg::new(kind, msg.stamp_ns, detail);
                assert_eq!(again.detail(), Ok(detail));
                assert_eq!(again.kind(), Ok(kind));
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

fn task_plan(bytes: &[u8]) {
    with_message::<TaskPlanMsg, _>(bytes, check_task_plan);
}

fn check_task_plan(msg: &TaskPlanMsg) {
    let _ = msg.stamp_ns();
    match msg.steps() {
        Ok(steps) => {
            assert_eq!(steps.len(), msg.step_count as usize);
            assert!(steps.len() <= MAX_TASK_STEPS);
            for step in steps {
                assert!(step.is_finite());
                let _ = step.kind();
                let _ = step.side();
                if let Ok(object) = step.object() {
                    assert!(object < grop_ipc::MAX_TASK_OBJECTS);
                }
            }
            let mut copy = zeroed::<TaskPlanMsg>();
            assert_eq!(copy.set_steps(steps), Ok(()));
            assert_eq!(copy.steps().map(raw_slice), Ok(raw_slice(steps)));
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

fn replan_request(bytes: &[u8]) {
    with_message::<ReplanRequestMsg, _>(bytes, check_replan_request);
}

fn check_replan_request(msg: &ReplanRequestMsg) {
    let _ = msg.stamp_ns();
    if let Ok(reason) = msg.reason() {
        let mut copy = *msg;
        copy.set_reason(reason);
        assert_eq!(copy.reason, msg.reason);
    }
}

fn heatmaps(bytes: &[u8]) {
    with_message::<HeatmapsMsg, _>(bytes, check_heatmaps);
}

fn check_heatmaps(msg: &HeatmapsMsg) {
    let _ = msg.stamp_ns();
    match msg.locations() {
        Ok(locations) => {
            assert_eq!(locations.len(), msg.count as usize);
            assert!(locations.len() <= MAX_HEATMAPS);
        }
        Err(e) => {
            let _ = e.to_string();
            assert!(msg.count as usize > MAX_HEATMAPS);
        }
    }
}

fn base_pose(bytes: &[u8]) {
    with_message::<BasePoseMsg, _>(bytes, check_base_pose);
}

fn check_base_pose(msg: &BasePoseMsg) {
    let _ = msg.stamp_ns();
    let kind = msg.kind();
    if let Ok(pose) = msg.pose() {
        assert!(pose.iter().all(|v| v.is_finite()));
        assert!(msg.sigma_xy_m >= 0.0 && msg.sigma_yaw_rad >= 0.0);
        if let Ok(kind) = kind {
            let again = BasePoseMsg::fix(
                msg.seq,
                msg.stamp_ns,
                kind,
                pose,
                msg.sigma_xy_m,
                msg.sigma_yaw_rad,
            );
            assert_eq!(again.pose(), Ok(pose));
            assert_eq!(again.kind(), Ok(kind));
        }
    }
}

fn heartbeat(bytes: &[u8]) {
    with_message::<HeartbeatMsg, _>(bytes, check_heartbeat);
}

fn check_heartbeat(msg: &HeartbeatMsg) {
    let _ = msg.stamp_ns();
    if let Ok(role) = msg.role() {
        let mut copy = *msg;
        copy.set_role(role);
        assert_eq!(raw(&copy), raw(msg));
    }
}

fn arm_io(bytes: &[u8]) {
    with_message::<ArmIoMsg, _>(bytes, check_arm_io);
}

fn check_arm_io(msg: &ArmIoMsg) {
    let _ = msg.stamp_ns();
    let _ = msg.call().map_err(|e| e.to_string());
    let _ = msg.outcome().map_err(|e| e.to_string());
    let finite = msg
        .joints_rad
        .iter()
        .chain(&msg.joint_speeds_radps)
        .chain(&msg.flange_pose)
        .all(|v| v.is_finite());
    assert_eq!(msg.is_finite(), finite);
}

fn camera_message(bytes: &[u8]) {
    with_message::<CameraFrameMsg, _>(bytes, check_camera_message);
}

fn check_camera_message(msg: &CameraFrameMsg) {
    let _ = msg.stamp_ns();
    match (msg.image(), msg.header.checked_len()) {
        (Ok(pixels), Ok(len)) => {
            let h = msg.header;
            assert_eq!(pixels.len(), len);
            assert!(len <= CAMERA_MAX_BYTES);
            assert_eq!(
                len as u64,
                u64::from(h.row_stride_bytes) * u64::from(h.height_px)
            );
        }
        (Err(a), Err(b)) => assert_eq!(a, b),
        (a, b) => panic!("image() {a:?} disagrees with checked_len() {b:?}"),
    }
}

/// The camera frame as the planner node reads it: header (the first 56 bytes, as the message
/// holds it), a target x (8 bytes), a fill byte, then pixel bytes. A header that checks gives an
/// image of `row_stride_bytes * height_px` bytes; the planner's layout of it passes the world's
/// own check, and both views cut from it either fail with an error or fill the crop. A frame of
/// one uniform gray (the fill byte, when bit 0 of the byte after it is set) cuts to views of
/// that gray wherever the view lies inside a sensibly scaled frame.
pub fn camera_frame(data: &[u8]) {
    let header_len = size_of::<CameraFrameHeader>();
    let header = with_message::<CameraFrameHeader, _>(data, |h| *h);
    let rest = data.get(header_len..).unwrap_or(&[]);
    let mut b = crate::bytes::Bytes::new(rest);
    let target_x = b.f64();
    let fill = b.u8();
    let uniform = b.u8() & 1 == 1;
    let pixels_in = b.rest();
    let len = match header.checked_len() {
        Ok(len) => len,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    assert!(len <= CAMERA_MAX_BYTES);
    assert_eq!(
        len as u64,
        u64::from(header.row_stride_bytes) * u64::from(header.height_px)
    );
    // The image part of a `CameraFrameMsg` (what `CameraFrameMsg::image` returns for this
    // header); only as large as the header asks, not the message's 3.5 MiB.
    let mut image = vec![0u8; len];
    if uniform {
        image.fill(fill);
    } else {
        let n = pixels_in.len().min(len);
        image[..n].copy_from_slice(&pixels_in[..n]);
    }
    let pixels = &image[..];
    // What the planner node builds from the header (runtime/processes/onboard/src/planner_node/single_trip.rs, `CameraFrameHeader::layout`).
    let layout = match header.layout() {
        Ok(layout) => layout,
        Err(e) => panic!("a checked header has no pixel format: {e}"),
    };
    assert_eq!(layout.check(pixels.len()), Ok(()), "{header:?}");
    let sane = (1e-3..=1.0).contains(&header.metres_per_px)
        && header.left_x_m.abs() < 1e3
        && header.top_y_m.abs() < 1e3;
    for side in [Side::Near, Side::Far] {
        let mut crop = [0u8; CROP_ROWS * CROP_COLS];
        match cut_view(pixels, &layout, target_x, side, &mut crop) {
            Ok(()) => {
                if uniform && sane {
                    assert!(
                        crop.iter().all(|g| *g == fill),
                        "uniform gray {fill} cut to other grays ({header:?}, x {target_x})"
                    );
                }
            }
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }
}
