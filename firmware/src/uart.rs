//! The CMSDK APB UART (ARM Cortex-M System Design Kit), as on the MPS2 boards and in QEMU's
//! `mps2-an386` / `mps2-an500`, behind the `embedded-io` traits the link is written against.
//!
//! Polled, no interrupts: one byte of receive and transmit buffer each (`STATE` bits 0/1).

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};

/// Register offsets (CMSDK APB UART technical reference, Table 4-3).
const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
/// `STATE` bits.
const TX_FULL: u32 = 1 << 0;
const RX_FULL: u32 = 1 << 1;
/// `CTRL` bits.
const TX_ENABLE: u32 = 1 << 0;
const RX_ENABLE: u32 = 1 << 1;

/// One CMSDK UART at its base address.
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// Enables transmitter and receiver with the baud divisor `clock / baud` (at least 16).
    ///
    /// # Safety
    /// `base` must be the address of a CMSDK APB UART that nothing else uses.
    pub unsafe fn new(base: usize, baud_divisor: u32) -> Self {
        let uart = Self { base };
        uart.write_register(BAUDDIV, baud_divisor.max(16));
        uart.write_register(CTRL, TX_ENABLE | RX_ENABLE);
        uart
    }

    fn read_register(&self, offset: usize) -> u32 {
        // SAFETY: `new`'s contract: a UART register block at `base`.
        unsafe { read_volatile((self.base + offset) as *const u32) }
    }

    fn write_register(&self, offset: usize, value: u32) {
        // SAFETY: as in `read_register`.
        unsafe { write_volatile((self.base + offset) as *mut u32, value) }
    }

    fn state(&self) -> u32 {
        self.read_register(STATE)
    }
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_io::ReadReady for CmsdkUart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.state() & RX_FULL != 0)
    }
}

impl embedded_io::Read for CmsdkUart {
    /// Waits for one byte and returns it (the receive buffer holds one).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Some(first) = buf.first_mut() else { return Ok(0) };
        while self.state() & RX_FULL == 0 {}
        *first = (self.read_register(DATA) & 0xFF) as u8;
        Ok(1)
    }
}

impl embedded_io::Write for CmsdkUart {
    /// Waits for room and sends one byte.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let Some(byte) = buf.first() else { return Ok(0) };
        while self.state() & TX_FULL != 0 {}
        self.write_register(DATA, u32::from(*byte));
        Ok(1)
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while self.state() & TX_FULL != 0 {}
        Ok(())
    }
}
