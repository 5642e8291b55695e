//! The event type every decoder produces and the network consumes.

/// One change-detection event: a pixel's log intensity crossed a contrast threshold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Event {
    /// Timestamp in µs (wrapping `u32`; the core only uses differences).
    pub t_us: u32,
    /// Column, 0 = left.
    pub x: u16,
    /// Row, 0 = top.
    pub y: u16,
    /// `true` for an ON event (intensity increased), `false` for OFF.
    pub on: bool,
}

/// An event with a full 64-bit timestamp, as produced by the stream decoders in [`crate::evt`].
///
/// The decoders extend the sensors' short timestamps (EVT 3.0: 24 bits, EVT 2.x: 34 bits) to a
/// monotonic 64-bit count of µs, so a recording of any length keeps its absolute time. The host
/// uses it as is; the firmware converts it with [`Event64::relative_to`] or
/// [`Event64::wrapping`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Event64 {
    /// Timestamp in µs since the decoder's time origin (never wraps in practice: 584 000 years).
    pub t_us: u64,
    /// Column, 0 = left.
    pub x: u16,
    /// Row, 0 = top.
    pub y: u16,
    /// `true` for an ON event (intensity increased), `false` for OFF.
    pub on: bool,
}

impl Event64 {
    /// The event with its time truncated to the low 32 bits (wraps every 71.6 minutes).
    #[inline(always)]
    #[must_use]
    pub const fn wrapping(self) -> Event {
        Event {
            t_us: self.t_us as u32,
            x: self.x,
            y: self.y,
            on: self.on,
        }
    }

    /// The event with its time made relative to `t0_us` (for example the first event's time) and
    /// truncated to a wrapping `u32`: `(t_us - t0_us) mod 2^32`.
    #[inline(always)]
    #[must_use]
    pub const fn relative_to(self, t0_us: u64) -> Event {
        Event {
            t_us: self.t_us.wrapping_sub(t0_us) as u32,
            x: self.x,
            y: self.y,
            on: self.on,
        }
    }
}
