//! The event clock: µs on a wrapping 32-bit counter, as sensors and the AER stream carry time.
//!
//! The counter wraps every 2^32 µs (71.6 min). Two times compare correctly while they are less
//! than 2^31 µs (35.8 min) apart: `b` is after `a` when `b - a` (wrapping) is in `1..2^31`.
//! The network keeps every stored time within that of the present (its round-robin refresh),
//! and the host cuts longer gaps into separate runs, so the rule holds wherever it is used.
//! Records that cross an interface ([`crate::event::Event`], yaw samples, frames) carry the raw
//! `u32`; arithmetic on them goes through [`EventTime`].

/// A time on the event clock (µs, wrapping; see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(transparent)]
pub struct EventTime(u32);

/// Half the clock's range: the largest distance two comparable times may have (µs).
pub const HALF_RANGE_US: u32 = 1 << 31;

impl EventTime {
    /// The time `us` µs on the clock.
    #[inline]
    pub const fn from_us(us: u32) -> Self {
        Self(us)
    }

    /// The raw counter value (µs).
    #[inline]
    pub const fn as_us(self) -> u32 {
        self.0
    }

    /// µs from `earlier` to `self`, or `None` when `earlier` is in fact later than `self`.
    #[inline]
    pub const fn since(self, earlier: Self) -> Option<u32> {
        let d = self.0.wrapping_sub(earlier.0);
        if d < HALF_RANGE_US {
            Some(d)
        } else {
            None
        }
    }

    /// µs from `earlier` to `self`, 0 when `earlier` is later.
    #[inline]
    pub const fn elapsed_since(self, earlier: Self) -> u32 {
        match self.since(earlier) {
            Some(d) => d,
            None => 0,
        }
    }

    /// Whether `self` is strictly after `other`.
    #[inline]
    pub const fn is_after(self, other: Self) -> bool {
        matches!(self.since(other), Some(d) if d != 0)
    }

    /// The time `us` µs later (wrapping).
    #[inline]
    #[must_use]
    pub const fn add_us(self, us: u32) -> Self {
        Self(self.0.wrapping_add(us))
    }
}

/// µs from `from` to `to` on the event clock, 0 when `from` is later (raw-counter form of
/// [`EventTime::elapsed_since`]).
#[inline]
pub const fn elapsed_us(from: u32, to: u32) -> u32 {
    EventTime::from_us(to).elapsed_since(EventTime::from_us(from))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comparisons_hold_across_the_wrap() {
        let a = EventTime::from_us(u32::MAX - 10);
        let b = a.add_us(20);
        assert_eq!(b.as_us(), 9);
        assert_eq!(b.since(a), Some(20));
        assert_eq!(a.since(b), None);
        assert!(b.is_after(a));
        assert!(!a.is_after(b));
        assert!(!a.is_after(a));
        assert_eq!(a.elapsed_since(b), 0);
        assert_eq!(elapsed_us(a.as_us(), b.as_us()), 20);
    }

    #[test]
    fn half_the_range_is_the_limit() {
        let a = EventTime::from_us(0);
        assert_eq!(
            a.add_us(HALF_RANGE_US - 1).since(a),
            Some(HALF_RANGE_US - 1)
        );
        assert_eq!(a.add_us(HALF_RANGE_US).since(a), None);
    }
}
