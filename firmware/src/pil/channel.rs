//! The binary `pil`'s channel to its board, the host: two files opened through
//! semihosting (ARM's semihosting `SYS_OPEN`, `SYS_READ`, `SYS_WRITE`), which
//! `host-sim run --firmware` makes named pipes in QEMU's working directory
//! (`docs/pil.md`). A semihosting call stops the core until the host has
//! answered it, and QEMU's virtual clock (`-icount`) counts instructions only, so
//! the exchange takes no firmware time however long the host takes.

use cortex_m_semihosting::{nr, syscall};

/// The host's records to the firmware (`shared::pil::Sample`), a path relative to
/// QEMU's working directory, NUL-terminated for `SYS_OPEN`.
const INPUT: &[u8] = b"pil.in\0";
/// The firmware's records to the host (`shared::pil::Hello`, `shared::pil::Drive`).
const OUTPUT: &[u8] = b"pil.out\0";

/// The channel failed: a file would not open, a read or write failed, or the
/// host closed its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct ChannelError;

/// The two open files, by their semihosting handles.
pub struct Channel {
    input: usize,
    output: usize,
}

impl Channel {
    /// Open both files: the input for reading, the output for writing (the order
    /// the host opens its ends in).
    pub fn open() -> Result<Channel, ChannelError> {
        let input = open(INPUT, nr::open::R_BINARY)?;
        let output = open(OUTPUT, nr::open::W_TRUNC_BINARY)?;
        Ok(Channel { input, output })
    }

    /// Write the whole of `bytes`.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), ChannelError> {
        let mut rest = bytes;
        while !rest.is_empty() {
            // SYS_WRITE returns the count of bytes *not* written.
            // SAFETY: the pointer and length are those of a live slice.
            let left = unsafe { syscall!(WRITE, self.output, rest.as_ptr(), rest.len()) };
            if left >= rest.len() {
                return Err(ChannelError);
            }
            rest = rest.get(rest.len() - left..).ok_or(ChannelError)?;
        }
        Ok(())
    }

    /// Fill the whole of `buf` (a pipe may deliver a record in pieces).
    pub fn receive(&mut self, buf: &mut [u8]) -> Result<(), ChannelError> {
        let mut done = 0;
        while done < buf.len() {
            let rest = buf.get_mut(done..).ok_or(ChannelError)?;
            // SYS_READ returns the count of bytes *not* read: all of them at the
            // end of the file (the host closed the pipe).
            // SAFETY: the pointer and length are those of a live mutable slice.
            let left = unsafe { syscall!(READ, self.input, rest.as_mut_ptr(), rest.len()) };
            if left >= rest.len() {
                return Err(ChannelError);
            }
            done += rest.len() - left;
        }
        Ok(())
    }
}

/// `SYS_OPEN` of the NUL-terminated `name` in `mode`.
fn open(name: &[u8], mode: usize) -> Result<usize, ChannelError> {
    // SAFETY: a NUL-terminated name; the length excludes the NUL.
    let handle = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len() - 1) };
    if handle as isize == -1 {
        Err(ChannelError)
    } else {
        Ok(handle)
    }
}
