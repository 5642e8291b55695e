//! Board support: each board provides the byte source, the yaw sink, the cost meter, the
//! executor, logging and the panic handler, and spawns the application's tasks.

#[cfg(any(
    all(feature = "board-qemu", feature = "board-stm32f405"),
    all(feature = "board-qemu", feature = "board-stm32h743"),
    all(feature = "board-stm32f405", feature = "board-stm32h743"),
))]
compile_error!(
    "choose one board: --no-default-features --features board-stm32f405 (or board-stm32h743)"
);

#[cfg(feature = "board-qemu")]
mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu::main;

#[cfg(all(feature = "board-stm32f405", not(feature = "board-qemu")))]
mod stm32f405;
#[cfg(all(feature = "board-stm32f405", not(feature = "board-qemu")))]
pub use stm32f405::main;

#[cfg(all(feature = "board-stm32h743", not(feature = "board-qemu")))]
mod stm32h743;
#[cfg(all(feature = "board-stm32h743", not(feature = "board-qemu")))]
pub use stm32h743::main;

/// Executors, yaw queue, cycle meter and tasks shared by the STM32 boards.
#[cfg(all(
    any(feature = "board-stm32f405", feature = "board-stm32h743"),
    not(feature = "board-qemu")
))]
mod stm32_common;
/// The SPI link (NSS edges, OVR, MODF) shared by the STM32 boards.
#[cfg(all(
    any(feature = "board-stm32f405", feature = "board-stm32h743"),
    not(feature = "board-qemu")
))]
mod stm32_link;
