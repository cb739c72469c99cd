//! The link over any `embedded-io` serial port: frames out, messages in,
//! never blocking on receive.

use embedded_io::{Read, ReadReady, Write};

use super::frame::{encode, Decoder, EncodeError, FrameError};
use super::message::{FromController, RxCounts, ToController};

/// Scratch for one unframed outgoing message (the largest,
/// [`FromController::Reading`], is about 70 bytes).
pub const TX_RAW: usize = 96;
/// One framed outgoing message.
pub const TX_FRAME: usize = super::frame::max_frame_len(TX_RAW);
/// The receive buffer: one incoming frame (odometry is about 20 bytes).
pub const RX_FRAME: usize = 64;

/// Why the link failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkError<E> {
    /// The serial port failed.
    Port(E),
    /// A message too large to frame (a bug, not a line fault).
    Encode(EncodeError),
}

/// A controller's end of the link over port `P`.
#[derive(Debug)]
pub struct Link<P> {
    port: P,
    rx: Decoder<RX_FRAME>,
    last_error: Option<FrameError>,
}

impl<P: Read + ReadReady + Write> Link<P> {
    /// Over `port`.
    pub fn new(port: P) -> Self {
        Self { port, rx: Decoder::new(), last_error: None }
    }

    /// Reads what the port has ready, at most `max_bytes` bytes, and
    /// returns the first message that completes. Never waits for a byte.
    pub fn poll(&mut self, max_bytes: usize) -> Result<Option<ToController>, LinkError<P::Error>> {
        for _ in 0..max_bytes {
            if !self.port.read_ready().map_err(LinkError::Port)? {
                return Ok(None);
            }
            let mut b = [0u8; 1];
            if self.port.read(&mut b).map_err(LinkError::Port)? == 0 {
                return Ok(None);
            }
            match self.rx.push::<ToController>(b[0]) {
                Some(Ok(m)) => return Ok(Some(m)),
                Some(Err(e)) => self.last_error = Some(e),
                None => {}
            }
        }
        Ok(None)
    }

    /// Frames and sends `msg`, blocking until the port has taken it.
    pub fn send(&mut self, msg: &FromController) -> Result<(), LinkError<P::Error>> {
        let mut frame = [0u8; TX_FRAME];
        let n = encode::<_, TX_RAW>(msg, &mut frame).map_err(LinkError::Encode)?;
        let frame = frame.get(..n).ok_or(LinkError::Encode(EncodeError::TooLarge))?;
        self.port.write_all(frame).map_err(LinkError::Port)?;
        self.port.flush().map_err(LinkError::Port)
    }

    /// Frames received so far, by fate.
    pub fn rx_counts(&self) -> RxCounts {
        self.rx.counts()
    }

    /// Why the last dropped frame was dropped.
    pub fn last_error(&self) -> Option<FrameError> {
        self.last_error
    }

    /// The port back.
    pub fn release(self) -> P {
        self.port
    }
}
