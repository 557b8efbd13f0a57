//! The control image: Justin's whole-body controller (`f32`, `controller_config`, configured
//! for the scenario by the setup message the host sends first: environment volumes, free
//! platform axes, hierarchy) at 1 kHz on the SysTick tick, the robot behind UART0 through the
//! `hal` traits (`firmware::serial_robot`: sensor and actuator frames of the `link` crate).
//! Logs through defmt, its frames on semihosting stdout (the host decodes them with the image's
//! `.defmt` table: `host-sim`'s PIL, or `defmt-print -e`): setup replies, link faults, output mode changes, and
//! once per second the cycles run, deadline misses and the worst cycle's cost; timestamps are
//! control ticks (ms). Runs until the board is reset (QEMU: killed); a panic is logged and ends
//! the QEMU run as a failure.
#![no_std]
#![no_main]

use core::panic::PanicInfo;

use cortex_m_rt::entry;
use cortex_m_semihosting::debug;
use defmt_semihosting as _;
use firmware::board::{self, Stopwatch};
use firmware::runtime::{ControllerSlot, PeriodReport, Robot, Runtime};

/// Periods without a sensor frame before the runtime holds: generous, because under QEMU the
/// host (simulating the robot in lockstep) shares the machine with the emulated core.
const WATCHDOG_PERIODS: u32 = 500;

defmt::timestamp!("{=u32:ms}", board::ticks());

// The controller (~90 KB in f32) lives in `.bss`, not on the stack.
static mut CONTROLLER: ControllerSlot = ControllerSlot::new();

fn log(report: &PeriodReport) {
    if let Some(reply) = report.setup {
        defmt::info!("setup {}", reply);
    }
    if let Some(fault) = report.link_fault {
        defmt::warn!("link fault {}", fault);
    }
    if let Some(mode) = report.mode_change {
        defmt::warn!("output mode {} (kernel fault code {=u8})", mode, report.fault_code);
    }
    if report.rejected_commands > 0 {
        defmt::warn!("{=u32} planner command(s) rejected", report.rejected_commands);
    }
    if let Some(stats) = report.stats {
        defmt::info!(
            "cycles {=u64} deadline misses {=u32} worst cycle {=u32} clock cycles link faults {=u32}",
            stats.cycles,
            stats.deadline_misses,
            stats.worst_cycle_cost,
            stats.link_faults
        );
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    exit_failure()
}

fn exit_failure() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[entry]
fn main() -> ! {
    // SAFETY: the only reference to CONTROLLER, taken once before the loop.
    let slot = unsafe { &mut *core::ptr::addr_of_mut!(CONTROLLER) };
    // The model is the same for every setup: built once, before the link is served.
    let Ok(model) = fixtures::justin::model::<f32>() else {
        defmt::error!("model construction failed");
        exit_failure()
    };
    let Some(peripherals) = cortex_m::Peripherals::take() else { exit_failure() };
    let mut robot = Robot::new(board::uart0(), WATCHDOG_PERIODS);
    let mut runtime = Runtime::new();
    let _systick = board::start_ticks(peripherals.SYST);
    defmt::info!("runtime: {=u32} Hz, UART0 at {=usize:#x}", board::TICK_HZ, board::UART0_BASE);
    let mut seen = board::ticks();
    loop {
        let now = board::wait_for_tick(seen);
        let missed = now.wrapping_sub(seen).saturating_sub(1);
        seen = now;
        let stopwatch = Stopwatch::start();
        let report = runtime.period(&mut robot, slot, &model, missed, || board::ticks() != now);
        if report.steps > 0 {
            runtime.record_cost(stopwatch.elapsed());
        }
        log(&report);
    }
}
