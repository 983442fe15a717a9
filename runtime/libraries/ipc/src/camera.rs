//! The overhead camera's frames (`camera/frame`): real-size RGB8 or Mono8 images of the whole
//! room with the metric header the planner node needs to cut Psi's 64 x 32 views out of them
//! (docs/architecture.md conventions: rows top-to-bottom = decreasing y, columns = increasing x).
//!
//! The message carries up to 1280 x 960 RGB8 with a row stride, like a camera driver delivers
//! it. As everywhere in this crate the bytes come from another process, so every
//! size and enum field is checked by the accessors, which return [`MessageError`], never panic.
#![allow(
    unsafe_code,
    reason = "the camera frame is written in place in the iceoryx2 loan (see the SAFETY comment)"
)]

use core::fmt;

use iceoryx2::prelude::ZeroCopySend;

use crate::messages::MessageError;

/// Widest frame the buffer holds.
pub const CAMERA_MAX_WIDTH_PX: u32 = 1280;
/// Tallest frame the buffer holds.
pub const CAMERA_MAX_HEIGHT_PX: u32 = 960;
/// Pixel buffer capacity in bytes: 1280 x 960 RGB8 (3.5 MiB).
pub const CAMERA_MAX_BYTES: usize = (CAMERA_MAX_WIDTH_PX * CAMERA_MAX_HEIGHT_PX * 3) as usize;

/// How a frame's pixels are encoded: `world::camera`'s enum, the one there is.
pub use world::camera::PixelFormat;
use world::camera::{FrameLayout, OverheadCamera};

/// The value [`CameraFrameHeader::pixel_format`] carries for `format`.
fn format_to_wire(format: PixelFormat) -> u32 {
    match format {
        PixelFormat::Rgb8 => 1,
        PixelFormat::Mono8 => 2,
    }
}

/// The pixel format a header carries, checked.
fn format_from_wire(value: u32) -> Result<PixelFormat, MessageError> {
    match value {
        1 => Ok(PixelFormat::Rgb8),
        2 => Ok(PixelFormat::Mono8),
        _ => Err(MessageError::UnknownEnumValue {
            message: "CameraFrameHeader",
            field: "pixel_format",
            value,
        }),
    }
}

/// Frame id, time, pixel layout and where the image lies in the world (a camera looking straight
/// down: pixel (row, col) covers x in `left_x_m + [col, col + 1] * metres_per_px`, y in
/// `top_y_m - [row + 1, row] * metres_per_px`).
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::CameraFrameHeader/v1")]
pub struct CameraFrameHeader {
    /// Camera frame counter, increasing.
    pub frame_id: u64,
    /// Capture time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// [`PixelFormat`] as an integer; read with [`CameraFrameHeader::pixel_format`].
    pub pixel_format: u32,
    /// Bytes from the start of one row to the start of the next (at least width x bytes/px).
    pub row_stride_bytes: u32,
    /// Edge length of one pixel on the floor, metres.
    pub metres_per_px: f64,
    /// World x of the left edge of column 0, metres.
    pub left_x_m: f64,
    /// World y of the top edge of row 0, metres.
    pub top_y_m: f64,
}

impl CameraFrameHeader {
    /// The pixel format, checked.
    pub fn pixel_format(&self) -> Result<PixelFormat, MessageError> {
        format_from_wire(self.pixel_format)
    }

    /// The header of frame `frame_id`, captured at `stamp_ns` on the runtime clock, with
    /// `layout`: the one conversion from the overhead camera's geometry (`world::camera`) to the
    /// message. A row stride beyond `u32` (no camera has one) saturates, and
    /// [`checked_len`](Self::checked_len) refuses it.
    pub fn for_layout(frame_id: u64, stamp_ns: u64, layout: &FrameLayout) -> Self {
        let camera = &layout.camera;
        Self {
            frame_id,
            stamp_ns,
            width_px: camera.width_px,
            height_px: camera.height_px,
            pixel_format: format_to_wire(layout.format),
            row_stride_bytes: u32::try_from(layout.row_stride_bytes).unwrap_or(u32::MAX),
            metres_per_px: camera.metres_per_px,
            left_x_m: camera.left_x_m,
            top_y_m: camera.top_y_m,
        }
    }

    /// The layout the header describes, for cutting views with `world::camera`: the one
    /// conversion back. An unknown pixel format is an error; the sizes are checked against the
    /// pixels by [`CameraFrameMsg::image`] and `FrameLayout::check`.
    pub fn layout(&self) -> Result<FrameLayout, MessageError> {
        Ok(FrameLayout {
            camera: OverheadCamera {
                width_px: self.width_px,
                height_px: self.height_px,
                metres_per_px: self.metres_per_px,
                left_x_m: self.left_x_m,
                top_y_m: self.top_y_m,
            },
            format: self.pixel_format()?,
            row_stride_bytes: self.row_stride_bytes as usize,
        })
    }

    /// Sets the pixel format.
    pub fn set_pixel_format(&mut self, format: PixelFormat) {
        self.pixel_format = format_to_wire(format);
    }

    /// Checks every field of the header against the buffer and returns the number of bytes the
    /// image occupies (`row_stride_bytes * height_px`).
    pub fn checked_len(&self) -> Result<usize, MessageError> {
        let format = self.pixel_format()?;
        let fits = self.width_px > 0
            && self.height_px > 0
            && self.width_px <= CAMERA_MAX_WIDTH_PX
            && self.height_px <= CAMERA_MAX_HEIGHT_PX;
        if !fits {
            return Err(MessageError::BadImageSize {
                width_px: self.width_px,
                height_px: self.height_px,
                max_width_px: CAMERA_MAX_WIDTH_PX,
                max_height_px: CAMERA_MAX_HEIGHT_PX,
            });
        }
        // Cannot overflow: both at most 1280 * 3.
        let row_bytes = self.width_px * format.bytes_per_px() as u32;
        if self.row_stride_bytes < row_bytes {
            return Err(MessageError::CountTooLarge {
                message: "CameraFrameHeader",
                field: "width_px * bytes per pixel (above row_stride_bytes)",
                count: u64::from(row_bytes),
                capacity: u64::from(self.row_stride_bytes),
            });
        }
        let len = u64::from(self.row_stride_bytes) * u64::from(self.height_px);
        if len > CAMERA_MAX_BYTES as u64 {
            return Err(MessageError::CountTooLarge {
                message: "CameraFrameHeader",
                field: "row_stride_bytes * height_px",
                count: len,
                capacity: CAMERA_MAX_BYTES as u64,
            });
        }
        let metric = [self.metres_per_px, self.left_x_m, self.top_y_m];
        if let Some(index) = metric.iter().position(|v| !v.is_finite()) {
            return Err(MessageError::NotFinite {
                message: "CameraFrameHeader",
                field: "[metres_per_px, left_x_m, top_y_m]",
                index: index as u32,
            });
        }
        if self.metres_per_px <= 0.0 {
            return Err(MessageError::NotFinite {
                message: "CameraFrameHeader",
                field: "metres_per_px (must be > 0)",
                index: 0,
            });
        }
        Ok(len as usize)
    }
}

/// One overhead camera frame (`camera/frame`), fixed size so it travels zero-copy.
#[derive(Clone, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::CameraFrameMsg/v1")]
pub struct CameraFrameMsg {
    /// Frame id, time, layout and geometry.
    pub header: CameraFrameHeader,
    /// Row-major pixels, `row_stride_bytes` per row; only the first
    /// `row_stride_bytes * height_px` bytes are meaningful.
    pub pixels: [u8; CAMERA_MAX_BYTES],
}

impl CameraFrameMsg {
    /// An all-zero frame on the heap (3.5 MiB: never build one on a stack), for a process that
    /// keeps frames of its own (a recorder's ring, a decoder's buffer).
    pub fn boxed_zeroed() -> Box<Self> {
        let layout = std::alloc::Layout::new::<Self>();
        // SAFETY: the layout is non-zero-sized; all-zero bytes are a valid CameraFrameMsg
        // (integers, floats and a byte array); a null result goes to the allocation error
        // handler; the Box takes ownership of memory allocated with its own layout.
        unsafe {
            let ptr = std::alloc::alloc_zeroed(layout).cast::<Self>();
            if ptr.is_null() {
                std::alloc::handle_alloc_error(layout);
            }
            Box::from_raw(ptr)
        }
    }

    /// The image bytes (`row_stride_bytes * height_px` of them) after checking the header.
    pub fn image(&self) -> Result<&[u8], MessageError> {
        let len = self.header.checked_len()?;
        Ok(&self.pixels[..len])
    }

    /// Sets `header` and returns the image bytes to fill in place (how a camera driver or the
    /// simulated camera renders into a loaned frame without a copy). The header is only stored
    /// if it checks.
    pub fn image_mut(&mut self, header: CameraFrameHeader) -> Result<&mut [u8], MessageError> {
        let len = header.checked_len()?;
        self.header = header;
        Ok(&mut self.pixels[..len])
    }

    /// Sets `header` and copies `pixels` (exactly `row_stride_bytes * height_px` bytes) in.
    pub fn set_image(
        &mut self,
        header: CameraFrameHeader,
        pixels: &[u8],
    ) -> Result<(), MessageError> {
        let len = header.checked_len()?;
        if pixels.len() != len {
            return Err(MessageError::CountTooLarge {
                message: "CameraFrameMsg",
                field: "pixels (must equal row_stride_bytes * height_px)",
                count: pixels.len() as u64,
                capacity: len as u64,
            });
        }
        self.header = header;
        self.pixels[..len].copy_from_slice(pixels);
        Ok(())
    }
}

impl fmt::Debug for CameraFrameMsg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CameraFrameMsg")
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(width_px: u32, height_px: u32, format: PixelFormat) -> CameraFrameHeader {
        let camera = OverheadCamera {
            width_px,
            height_px,
            metres_per_px: 0.03125,
            left_x_m: -10.0,
            top_y_m: 11.5,
        };
        CameraFrameHeader::for_layout(
            1,
            2,
            &FrameLayout {
                camera,
                format,
                row_stride_bytes: width_px as usize * format.bytes_per_px(),
            },
        )
    }

    /// The one conversion between `world::camera`'s layout and the header: there and back
    /// unchanged, an unknown format refused, the wire values fixed.
    #[test]
    fn a_layout_goes_through_the_header_and_back_unchanged() {
        let camera = OverheadCamera {
            width_px: 640,
            height_px: 480,
            metres_per_px: 0.0125,
            left_x_m: -0.5,
            top_y_m: 8.25,
        };
        let padded = FrameLayout {
            camera,
            format: PixelFormat::Mono8,
            row_stride_bytes: 648,
        };
        for layout in [FrameLayout::rgb8(camera), padded] {
            let header = CameraFrameHeader::for_layout(9, 1_500, &layout);
            assert_eq!((header.frame_id, header.stamp_ns), (9, 1_500));
            assert!(header.checked_len().is_ok());
            assert_eq!(header.layout(), Ok(layout));
        }
        assert_eq!(header(1, 1, PixelFormat::Rgb8).pixel_format, 1);
        assert_eq!(header(1, 1, PixelFormat::Mono8).pixel_format, 2);
        let mut unknown = header(640, 480, PixelFormat::Rgb8);
        unknown.pixel_format = 7;
        assert!(unknown.layout().is_err());
    }

    /// The layout is the protocol between processes: a change must bump the `/vN` type names.
    #[test]
    fn wire_sizes_are_fixed() {
        assert_eq!(size_of::<CameraFrameHeader>(), 56);
        assert_eq!(size_of::<CameraFrameMsg>(), 56 + CAMERA_MAX_BYTES);
        assert_eq!(CAMERA_MAX_BYTES, 1280 * 960 * 3);
    }

    #[test]
    fn good_headers_check_and_bad_ones_are_errors() {
        assert_eq!(
            header(640, 480, PixelFormat::Rgb8).checked_len(),
            Ok(640 * 480 * 3)
        );
        assert_eq!(
            header(1280, 960, PixelFormat::Rgb8).checked_len(),
            Ok(CAMERA_MAX_BYTES)
        );
        let mut padded = header(640, 480, PixelFormat::Mono8);
        padded.row_stride_bytes = 704;
        assert_eq!(padded.checked_len(), Ok(704 * 480));

        let zeroed = CameraFrameHeader {
            pixel_format: 0,
            ..header(0, 0, PixelFormat::Rgb8)
        };
        assert!(matches!(
            zeroed.checked_len(),
            Err(MessageError::UnknownEnumValue { .. })
        ));
        assert!(matches!(
            header(0, 480, PixelFormat::Rgb8).checked_len(),
            Err(MessageError::BadImageSize { .. })
        ));
        assert!(matches!(
            header(1281, 10, PixelFormat::Mono8).checked_len(),
            Err(MessageError::BadImageSize { .. })
        ));
        let mut short_stride = header(640, 480, PixelFormat::Rgb8);
        short_stride.row_stride_bytes = 640;
        assert!(short_stride.checked_len().is_err());
        let mut long_stride = header(1280, 960, PixelFormat::Rgb8);
        long_stride.row_stride_bytes = u32::MAX;
        assert!(matches!(
            long_stride.checked_len(),
            Err(MessageError::CountTooLarge { .. })
        ));
        for bad in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            let mut h = header(640, 480, PixelFormat::Rgb8);
            h.metres_per_px = bad;
            assert!(h.checked_len().is_err(), "metres_per_px {bad}");
        }
        let mut h = header(640, 480, PixelFormat::Rgb8);
        h.top_y_m = f64::NAN;
        assert!(h.checked_len().is_err());
    }

    #[test]
    fn images_are_set_and_read_back() {
        let mut frame: Box<CameraFrameMsg> = CameraFrameMsg::boxed_zeroed();
        assert!(frame.image().is_err(), "a zeroed frame has no image");
        let h = header(4, 2, PixelFormat::Rgb8);
        let pixels: Vec<u8> = (0..24).collect();
        frame.set_image(h, &pixels).unwrap();
        assert_eq!(frame.image().unwrap(), &pixels[..]);
        assert!(frame.set_image(h, &pixels[..23]).is_err());
        let slot = frame.image_mut(header(2, 2, PixelFormat::Mono8)).unwrap();
        assert_eq!(slot.len(), 4);
        slot.fill(7);
        assert_eq!(frame.image().unwrap(), &[7, 7, 7, 7]);
        assert!(frame.image_mut(header(0, 2, PixelFormat::Mono8)).is_err());
        assert_eq!(frame.header.width_px, 2, "a bad header is not stored");
    }
}
