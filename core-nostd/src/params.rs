//! Parameters of one Time Difference Encoder unit, in the integer / fixed-point units the core
//! computes with. Defaults are those of `shared/spec/model.md` (the paper's simulation tables plus
//! the gain `g = 1e5 /s`).

use fixed::types::{U16F16, U5F27};

use crate::exp_table::MAX_TAU_US;

/// A FAC or TRG trace value: U5F27 (resolution 7.5e-9). Traces need this precision: the last
/// spikes of a burst start near the tangent point of the membrane curve, where a relative trace
/// error `e` moves the spike by about `tau · sqrt(2 e)`; 27 fractional bits keep that within a
/// few µs where 16 bits would cost hundreds.
pub type Trace = U5F27;

/// Largest value a FAC or TRG trace may hold (just below 16). Traces saturate here, which bounds
/// the length of any burst and therefore the work per event; it also leaves the top bit of a
/// stored trace free for flags.
pub const TRACE_MAX: Trace = Trace::from_bits(0x7FFF_FFFF);

/// FAC time constant of the slow units (µs): TDE units that differ from the paper's only in
/// `tau_F`, for edges too slow for the 20 ms units (see the calibrated readout). A unit bursts
/// when its drive reaches about `1/14.7` of `w_F`, so it times crossings up to about
/// `2.7 tau_F`: 54 ms for the paper's units, 270 ms for these.
pub const TAU_SLOW_US: u32 = 100_000;

/// Parameters of the TDE unit (`model.md`):
///
/// ```text
/// dI_F/dt = -I_F/tau_F + w_F Σ δ(t - t_FAC)
/// dI_T/dt = -I_T/tau_T + w_T I_F(t-) Σ δ(t - t_TRG)
/// du/dt   = -u/tau_m + g I_T ;  u >= theta => spike, u := 0, held at 0 for t_ref
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TdeParams {
    /// FAC trace time constant `tau_F` (µs).
    pub tau_fac_us: u32,
    /// TRG trace time constant `tau_T` (µs).
    pub tau_trg_us: u32,
    /// Membrane time constant `tau_m` (µs). The fixed-point core requires `tau_m == tau_T`;
    /// the f64 oracle accepts any value.
    pub tau_mem_us: u32,
    /// FAC weight `w_F` (dimensionless).
    pub w_fac: U16F16,
    /// TRG weight `w_T` (dimensionless).
    pub w_trg: U16F16,
    /// Firing threshold `theta` (same unit as `u`).
    pub theta: U16F16,
    /// Gain `g` from TRG trace to membrane, in 1/s.
    pub gain_per_s: u32,
    /// Refractory period `t_ref` (µs) during which `u` is held at 0 after a spike; at least 1 µs.
    pub t_ref_us: u32,
}

impl TdeParams {
    /// The defaults of `model.md`: all time constants 20 ms, weights 1, threshold 50,
    /// `g = 1e5 /s`, `t_ref = 0.1 ms`.
    pub const DEFAULT: Self = Self {
        tau_fac_us: 20_000,
        tau_trg_us: 20_000,
        tau_mem_us: 20_000,
        w_fac: U16F16::ONE,
        w_trg: U16F16::ONE,
        theta: U16F16::const_from_int(50),
        gain_per_s: 100_000,
        t_ref_us: 100,
    };

    /// Checks the ranges every model accepts.
    pub fn validate(&self) -> Result<(), ParamError> {
        for (name, tau) in [
            ("tau_fac", self.tau_fac_us),
            ("tau_trg", self.tau_trg_us),
            ("tau_mem", self.tau_mem_us),
        ] {
            if tau == 0 || tau > MAX_TAU_US {
                return Err(ParamError::TimeConstant(name));
            }
        }
        if self.theta == U16F16::ZERO {
            return Err(ParamError::Threshold);
        }
        if self.gain_per_s == 0 {
            return Err(ParamError::Gain);
        }
        if self.t_ref_us == 0 || self.t_ref_us > MAX_REFRACTORY_US {
            return Err(ParamError::Refractory);
        }
        Ok(())
    }

    /// Checks what the fixed-point core additionally needs (equal TRG and membrane time constants).
    pub fn validate_fixed(&self) -> Result<(), ParamError> {
        self.validate()?;
        if self.tau_trg_us != self.tau_mem_us {
            return Err(ParamError::UnequalTimeConstants);
        }
        Ok(())
    }
}

impl Default for TdeParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Longest refractory period (µs) the compact network state can hold.
pub const MAX_REFRACTORY_US: u32 = 0x7FFE;

/// A parameter outside the range the models accept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamError {
    /// A time constant is 0 or above 1 s (names which one).
    TimeConstant(&'static str),
    /// The threshold is zero.
    Threshold,
    /// The gain is zero.
    Gain,
    /// The refractory period is 0 or above 32.766 ms.
    Refractory,
    /// The fixed-point core needs `tau_trg == tau_mem`.
    UnequalTimeConstants,
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::TimeConstant(name) => write!(f, "{name} must be between 1 µs and 1 s"),
            Self::Threshold => f.write_str("theta must be positive"),
            Self::Gain => f.write_str("gain must be positive"),
            Self::Refractory => f.write_str("t_ref must be between 1 µs and 32.766 ms"),
            Self::UnequalTimeConstants => {
                f.write_str("the fixed-point core needs tau_trg == tau_mem (the oracle does not)")
            }
        }
    }
}
