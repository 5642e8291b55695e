//! Network layouts: which pixels carry TDE units, and where their state lives.
//!
//! Storage is organised by *cell*: one cell per pixel that the layout uses. A cell holds that
//! pixel's FAC trace and the (up to) two units that the pixel *triggers*:
//! - [`Dir::LeftToRight`]: FAC = `(x - s, y)`, TRG = `(x, y)` — prefers motion to the right;
//! - [`Dir::RightToLeft`]: FAC = `(x + s, y)`, TRG = `(x, y)` — prefers motion to the left.
//!
//! An event at a pixel therefore updates one FAC trace and triggers at most the two units of the
//! same cell, reading the FAC traces of the cells `s` pixels to its left and right.

/// Orientation of a unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dir {
    /// FAC on the left, TRG on the right: responds to rightward image motion.
    LeftToRight = 0,
    /// FAC on the right, TRG on the left: responds to leftward image motion.
    RightToLeft = 1,
}

impl Dir {
    /// Both orientations, in slot order.
    pub const BOTH: [Dir; 2] = [Dir::LeftToRight, Dir::RightToLeft];

    /// Slot of this orientation inside a cell (0 or 1).
    pub const fn slot(self) -> usize {
        self as usize
    }

    /// Horizontal offset (pixels, times the stride) from the TRG pixel to the FAC pixel.
    pub const fn fac_offset_sign(self) -> i32 {
        match self {
            Dir::LeftToRight => -1,
            Dir::RightToLeft => 1,
        }
    }
}

/// Which units exist in a cell: bit 0 = left-to-right, bit 1 = right-to-left.
pub type UnitMask = u8;

/// A network layout: a map from pixels to cells, and which units each cell has.
pub trait Layout {
    /// Number of cells (state slots) the layout needs.
    fn cell_count(&self) -> usize;
    /// Number of units in the layout.
    fn unit_count(&self) -> usize;
    /// FAC-to-TRG distance in pixels.
    fn stride(&self) -> u16;
    /// Sensor width and height in pixels (events outside are ignored).
    fn sensor(&self) -> (u16, u16);
    /// The cell of pixel `(x, y)`, if the layout uses that pixel.
    fn cell(&self, x: u16, y: u16) -> Option<usize>;
    /// Units present in cell `cell`.
    fn units(&self, cell: usize) -> UnitMask;
    /// Pixel coordinates of cell `cell`.
    fn pixel(&self, cell: usize) -> (u16, u16);
}

/// Every pixel pair at the stride, both orientations, over a window of the sensor.
///
/// With the full 346 x 260 sensor and stride 2 this is the paper's 178,880 units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dense {
    sensor_w: u16,
    sensor_h: u16,
    x0: u16,
    y0: u16,
    w: u16,
    h: u16,
    stride: u16,
}

impl Dense {
    /// The whole sensor. `stride` must be at least 1 and smaller than `width`.
    pub const fn new(width: u16, height: u16, stride: u16) -> Option<Self> {
        Self::window(width, height, 0, 0, width, height, stride)
    }

    /// A `w` x `h` window at `(x0, y0)` of a `width` x `height` sensor.
    pub const fn window(
        width: u16,
        height: u16,
        x0: u16,
        y0: u16,
        w: u16,
        h: u16,
        stride: u16,
    ) -> Option<Self> {
        if stride == 0 || w <= stride || h == 0 {
            return None;
        }
        if x0 as u32 + w as u32 > width as u32 || y0 as u32 + h as u32 > height as u32 {
            return None;
        }
        Some(Self {
            sensor_w: width,
            sensor_h: height,
            x0,
            y0,
            w,
            h,
            stride,
        })
    }

    /// Window width and height.
    pub const fn size(&self) -> (u16, u16) {
        (self.w, self.h)
    }
}

impl Layout for Dense {
    fn cell_count(&self) -> usize {
        self.w as usize * self.h as usize
    }

    fn unit_count(&self) -> usize {
        2 * (self.w - self.stride) as usize * self.h as usize
    }

    fn stride(&self) -> u16 {
        self.stride
    }

    fn sensor(&self) -> (u16, u16) {
        (self.sensor_w, self.sensor_h)
    }

    #[inline]
    fn cell(&self, x: u16, y: u16) -> Option<usize> {
        let cx = x.checked_sub(self.x0)?;
        let cy = y.checked_sub(self.y0)?;
        if cx >= self.w || cy >= self.h {
            return None;
        }
        Some(cy as usize * self.w as usize + cx as usize)
    }

    #[inline]
    fn units(&self, cell: usize) -> UnitMask {
        let w = self.w as usize;
        let cx = if w == 0 { 0 } else { cell % w };
        let s = self.stride as usize;
        let lr = u8::from(cx >= s);
        let rl = u8::from(cx + s < w);
        lr | (rl << 1)
    }

    fn pixel(&self, cell: usize) -> (u16, u16) {
        let w = self.w as usize;
        if w == 0 {
            return (self.x0, self.y0);
        }
        let cx = (cell % w) as u16;
        let cy = (cell / w) as u16;
        (self.x0.saturating_add(cx), self.y0.saturating_add(cy))
    }
}
