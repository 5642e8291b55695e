//! Board support: each board provides the byte source, the yaw sink, the cost meter, the
//! executor, logging and the panic handler, and spawns the application's tasks.

#[cfg(all(feature = "board-qemu", feature = "board-stm32f405"))]
compile_error!("choose one board: --no-default-features --features board-stm32f405");

#[cfg(feature = "board-qemu")]
mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu::main;

#[cfg(all(feature = "board-stm32f405", not(feature = "board-qemu")))]
mod stm32f405;
#[cfg(all(feature = "board-stm32f405", not(feature = "board-qemu")))]
pub use stm32f405::main;
