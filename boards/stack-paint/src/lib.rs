//! Stack high-water marks by painting, shared by the boards: cortex-m-rt
//! (feature `paint-stack`) fills the whole stack with its paint word before
//! `main`; the lowest word no longer holding it marks the deepest use since.
//! A board may also paint the free stack again below its current frame
//! ([`paint_free_stack`]) to measure one stretch of code alone.
#![no_std]

/// The stack's bounds `(top, bottom)`: cortex-m-rt's `_stack_start` and
/// `_stack_end` (linked with flip-link, the stack runs from just below
/// `.data` down to the start of RAM).
pub fn stack_bounds() -> (usize, usize) {
    extern "C" {
        static _stack_start: u32;
        static _stack_end: u32;
    }
    // Only the symbols' addresses are taken: no unsafe needed.
    (core::ptr::addr_of!(_stack_start) as usize, core::ptr::addr_of!(_stack_end) as usize)
}

/// The first word in `from..to` that no longer holds cortex-m-rt's paint
/// value (or `to`): the deepest stack use since the words were painted.
/// Always inlined, so that its own frame does not scrub what it reads.
#[inline(always)]
pub fn first_unpainted(from: usize, to: usize) -> usize {
    let mut p = from;
    // SAFETY: `from..to` is the stack's range (`stack_bounds`), plain RAM,
    // word-aligned; the reads are volatile and the words below the stack
    // pointer belong to no one.
    while p < to && unsafe { core::ptr::read_volatile(p as *const u32) } == cortex_m_rt::STACK_PAINT_VALUE {
        p += 4;
    }
    p
}

/// Paints the free stack, from its bottom up to the current stack pointer,
/// with cortex-m-rt's paint value; returns the stack pointer. Inlined into the
/// caller, so that no frame of its own lies below the pointer it reads.
#[inline(always)]
pub fn paint_free_stack(bottom: usize) -> usize {
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = bottom;
    while p < sp {
        // SAFETY: the words from the stack's bottom up to the stack pointer
        // are free (no interrupt is enabled), and nothing below it is live.
        unsafe { core::ptr::write_volatile(p as *mut u32, cortex_m_rt::STACK_PAINT_VALUE) };
        p += 4;
    }
    sp
}

/// Bytes of stack ever used since reset, and the stack's size.
pub fn stack_high_water() -> (usize, usize) {
    let (top, bottom) = stack_bounds();
    (top - first_unpainted(bottom, top), top - bottom)
}
