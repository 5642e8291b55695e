//! The processing stage: [`core_nostd::pipeline::Pipeline`] (network, calibrated readout, one
//! yaw sample per period on the event clock), built exactly as `host-sim run` (default
//! `--readout calibrated`) builds it, so that a QEMU replay gives the host's output bit for bit.
//! Keep the two in step: this module is the firmware's only knowledge of how.

use core_nostd::fixed::types::U16F16;
use core_nostd::layout::Layout;
use core_nostd::network::NetError;
use core_nostd::pipeline::Pipeline;
use core_nostd::readout::calibrated::{Calibrated, Calibration};
use core_nostd::unit::Kernel;

pub use core_nostd::network::Cell;
pub use core_nostd::readout::YawSample;

/// What the processing needs besides the layout.
#[derive(Clone, Copy, Debug)]
pub struct ProcessConfig {
    /// Focal length in px.
    pub focal_px: U16F16,
    /// Principal point column in px.
    pub cx: U16F16,
    /// Principal point row in px.
    pub cy: U16F16,
    /// Output period in µs (1000 = 1 kHz).
    pub period_us: u32,
}

/// The pipeline the firmware runs.
pub type Processor<'a, L> = Pipeline<'a, L, Calibrated>;

/// Builds the pipeline over `layout` with state in `cells` (`layout.cell_count()` of them).
pub fn build<'a, L: Layout>(
    kernel: &'a Kernel,
    layout: L,
    cells: &'a mut [Cell],
    cfg: &ProcessConfig,
) -> Result<Processor<'a, L>, NetError> {
    let cal = Calibration {
        period_us: cfg.period_us,
        ..Calibration::for_units(cfg.focal_px, cfg.cx, cfg.cy, layout.unit_count())
    };
    core_nostd::pipeline::calibrated(kernel, layout, cells, cal)
}
