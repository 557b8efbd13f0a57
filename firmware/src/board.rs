//! The QEMU MPS2 boards (`mps2-an500` Cortex-M7, `mps2-an386` Cortex-M4F): UART0 and the 1 kHz
//! control tick from SysTick.
//!
//! The SysTick exception only counts ticks ([`ticks`]); the control task runs in thread mode,
//! woken by it ([`wait_for_tick`]). A cycle's cost is read from SysTick's down-counter
//! ([`Stopwatch`]), in core clock cycles.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::exception;

use crate::uart::CmsdkUart;

/// Core clock of the MPS2 FPGA images QEMU models (25 MHz).
pub const CORE_CLOCK_HZ: u32 = 25_000_000;
/// Control rate.
pub const TICK_HZ: u32 = 1_000;
/// SysTick counts per tick.
pub const TICK_COUNTS: u32 = CORE_CLOCK_HZ / TICK_HZ;
/// UART0 of both boards.
pub const UART0_BASE: usize = 0x4000_4000;
/// Line rate of the link (QEMU ignores it; a real UART needs the host to match).
pub const BAUD: u32 = 115_200;

static TICKS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    TICKS.fetch_add(1, Ordering::Relaxed);
}

/// Ticks since [`start_ticks`].
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// Starts the 1 kHz SysTick interrupt from the core clock.
pub fn start_ticks(mut syst: SYST) -> SYST {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(TICK_COUNTS - 1);
    syst.clear_current();
    syst.enable_counter();
    syst.enable_interrupt();
    syst
}

/// Sleeps until the tick counter differs from `seen`; returns the new count.
pub fn wait_for_tick(seen: u32) -> u32 {
    loop {
        let now = ticks();
        if now != seen {
            return now;
        }
        cortex_m::asm::wfi();
    }
}

/// UART0 at the link's line rate.
pub fn uart0() -> CmsdkUart {
    // SAFETY: UART0 of the MPS2 boards; only the runtime uses it.
    unsafe { CmsdkUart::new(UART0_BASE, CORE_CLOCK_HZ / BAUD) }
}

/// The time since a start point, from the tick count and SysTick's down-counter.
pub struct Stopwatch {
    ticks: u32,
    counter: u32,
}

impl Stopwatch {
    /// Starts now.
    pub fn start() -> Self {
        let (ticks, counter) = now();
        Self { ticks, counter }
    }

    /// Core clock cycles since [`Stopwatch::start`] (saturating).
    pub fn elapsed(&self) -> u32 {
        let (ticks, counter) = now();
        let whole = ticks.wrapping_sub(self.ticks).saturating_mul(TICK_COUNTS);
        (whole + self.counter).saturating_sub(counter)
    }
}

/// The tick count and the SysTick counter read together (again if a tick came in between).
fn now() -> (u32, u32) {
    loop {
        let before = ticks();
        let counter = SYST::get_current();
        if ticks() == before {
            return (before, counter);
        }
    }
}
