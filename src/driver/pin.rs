//! A stand-in for a pin the board does not have.

use core::marker::PhantomData;

use embedded_hal::digital::{Error, ErrorType, OutputPin};

/// An output that is not wired: every write succeeds and does nothing.
///
/// Used for a module without a BINH line, and as the address-line type of a
/// module without a multiplexer (`[NoPin<E>; 0]`). It carries the HAL's error
/// type so that every pin of a module shares one `E`.
#[derive(Debug)]
pub struct NoPin<E>(PhantomData<fn() -> E>);

impl<E> NoPin<E> {
    /// A new unwired output.
    pub const fn new() -> Self {
        Self(PhantomData)
    }
}

impl<E> Default for NoPin<E> {
    fn default() -> Self {
        Self::new()
    }
}

impl<E: Error> ErrorType for NoPin<E> {
    type Error = E;
}

impl<E: Error> OutputPin for NoPin<E> {
    fn set_low(&mut self) -> Result<(), E> {
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), E> {
        Ok(())
    }
}
