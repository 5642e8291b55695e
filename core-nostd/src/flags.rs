//! Status bits of a yaw sample: the one set the pipeline, the firmware's yaw frames and
//! `host-sim run`'s CSV all use (bit values are the wire format's, `docs/wire-formats.md`).
//!
//! | bit | name | set by |
//! |---|---|---|
//! | 0 | [`STALE`] | the pipeline |
//! | 1 | [`NO_EVIDENCE`] | the readout |
//! | 2 | [`OVERFLOW`] | the firmware (input or output lost to overload); the pipeline (unit inputs lost to a full unit pool) |
//! | 3 | [`DECODER_ERRORS`] | the firmware |
//! | 4 | [`INPUT_ERRORS`] | the firmware |
//! | 5 | [`CLOCK`] | the firmware (live link) |
//! | 6 | [`RESTART`] | `host-sim` (its output only; never on the wire) |
//! | 7 | reserved (0) | |
//!
//! Flags raised by the firmware are sticky until the next yaw frame: they say that something
//! happened since the previous one.

/// No event for more than the stale limit (100 ms): the value says nothing about now.
pub const STALE: u8 = 1 << 0;
/// The evidence did not pass the readout's gate (the first 20 ms; motion in too few column
/// bands, or none in the upper row bands, as of objects moving on the ground; a field split
/// in direction, as just after a reversal; decodes that have all but stopped; the first
/// reading that answers after such a stretch, until the next agrees in sign, unless it
/// resumes within 12 ms with the sign it had). The value is 0, meaning "unknown", not "zero
/// rate": it is not a measurement, and a flight controller should treat the sample as none
/// (e.g. fall back to its gyro for it) rather than as the camera standing still.
pub const NO_EVIDENCE: u8 = 1 << 1;
/// Input was lost to overload: whole frames dropped because processing fell behind, the
/// sender reported lost events (SOURCE_OVERFLOW), yaw frames were dropped on output, or the
/// network's unit pool was full (unit inputs lost, `crate::network::pool`).
pub const OVERFLOW: u8 = 1 << 2;
/// Payload decoder errors (EVT 3.0 words of undefined types).
pub const DECODER_ERRORS: u8 = 1 << 3;
/// Corrupted input: frames rejected (CRC, header), missing from the sequence, or bytes lost by
/// the receiver (DMA overrun).
pub const INPUT_ERRORS: u8 = 1 << 4;
/// The sample's time was extrapolated with the MCU clock (no events were arriving), not taken
/// from event time.
pub const CLOCK: u8 = 1 << 5;
/// The pipeline restarted at this sample after a gap or a backward jump of the recording's
/// clock (`host-sim`'s time-gap policy). Host output only.
pub const RESTART: u8 = 1 << 6;
/// Bits a yaw frame may carry (bit 6 and 7 never go on the wire).
pub const WIRE_MASK: u8 = 0x3F;
