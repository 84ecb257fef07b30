//! Memory mapped from the system for what the search holds per state, so
//! it grows without copying and goes back when the search ends.

/// A growable run of zeroed bytes, mapped from the system in 2 MB pages
/// where the kernel leaves that to the program: each edge lands on a random
/// slot of the table, and with 4 KB pages nearly every one also misses the
/// TLB, which stalls even a prefetch. It grows by remapping, which copies
/// nothing (a heap allocation advised in part is split in two mappings,
/// which then cannot be remapped and are copied, holding the table twice
/// for a moment), and gives its pages back when dropped.
#[cfg(target_os = "linux")]
pub(crate) struct Pages {
    start: *mut u8,
    len: usize,
    mapped: usize,
    /// Whether to ask for 2 MB pages.
    huge: bool,
}

// SAFETY: Pages owns its mapping, as a Vec owns its buffer.
#[cfg(target_os = "linux")]
unsafe impl Send for Pages {}

#[cfg(target_os = "linux")]
impl Pages {
    /// `len` zero bytes; in 2 MB pages if `huge`.
    pub(crate) fn zeroed(len: usize, huge: bool) -> Pages {
        let mut pages = Pages {
            start: std::ptr::NonNull::dangling().as_ptr(),
            len: 0,
            mapped: 0,
            huge,
        };
        pages.resize(len);
        pages
    }

    /// Lengthens the run to `len` bytes, the new ones zero.
    pub(crate) fn resize(&mut self, len: usize) {
        debug_assert!(len >= self.len, "the run only grows");
        let want = len.next_multiple_of(4096);
        if want > self.mapped {
            // SAFETY: a fresh anonymous mapping, or the one this owns
            // remapped whole; on failure nothing is mapped anew.
            let start = unsafe {
                if self.mapped == 0 {
                    libc::mmap(
                        std::ptr::null_mut(),
                        want,
                        libc::PROT_READ | libc::PROT_WRITE,
                        libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                        -1,
                        0,
                    )
                } else {
                    libc::mremap(self.start.cast(), self.mapped, want, libc::MREMAP_MAYMOVE)
                }
            };
            if start == libc::MAP_FAILED {
                let layout =
                    std::alloc::Layout::from_size_align(want, 4096).expect("a page-aligned size");
                std::alloc::handle_alloc_error(layout);
            }
            if self.huge {
                // SAFETY: the advice covers exactly the mapping just made; it
                // changes neither contents nor mapping, and a refusal is
                // harmless.
                unsafe { libc::madvise(start, want, libc::MADV_HUGEPAGE) };
            }
            self.start = start.cast();
            self.mapped = want;
        }
        self.len = len;
    }
}

#[cfg(target_os = "linux")]
impl Drop for Pages {
    fn drop(&mut self) {
        if self.mapped > 0 {
            // SAFETY: the mapping is this one's own, and nothing borrows it.
            unsafe { libc::munmap(self.start.cast(), self.mapped) };
        }
    }
}

#[cfg(target_os = "linux")]
impl std::ops::Deref for Pages {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        // SAFETY: `len` bytes from `start` are mapped, readable and
        // initialised (zero or written); `start` is non-null and aligned.
        unsafe { std::slice::from_raw_parts(self.start, self.len) }
    }
}

#[cfg(target_os = "linux")]
impl std::ops::DerefMut for Pages {
    fn deref_mut(&mut self) -> &mut [u8] {
        // SAFETY: as for Deref, and `&mut self` makes the borrow unique.
        unsafe { std::slice::from_raw_parts_mut(self.start, self.len) }
    }
}

/// Elsewhere, a plain buffer.
#[cfg(not(target_os = "linux"))]
pub(crate) struct Pages(Vec<u8>);

#[cfg(not(target_os = "linux"))]
impl Pages {
    pub(crate) fn zeroed(len: usize, _huge: bool) -> Pages {
        Pages(vec![0; len])
    }

    pub(crate) fn resize(&mut self, len: usize) {
        self.0.resize(len, 0);
    }
}

#[cfg(not(target_os = "linux"))]
impl std::ops::Deref for Pages {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.0
    }
}

#[cfg(not(target_os = "linux"))]
impl std::ops::DerefMut for Pages {
    fn deref_mut(&mut self) -> &mut [u8] {
        &mut self.0
    }
}

/// A stack of numbers of `width` bytes (1 to 8) in [`Pages`]: the path's
/// frames and what each has left run as deep as the state space is large,
/// and a vector's doublings would leave the buffers it outgrew behind in
/// the heap.
pub(crate) struct Stack {
    width: usize,
    len: usize,
    pages: Pages,
}

impl Stack {
    pub(crate) fn new(width: usize) -> Stack {
        debug_assert!((1..=8).contains(&width));
        Stack {
            width,
            len: 0,
            pages: Pages::zeroed(0, false),
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The bits of one number.
    fn mask(&self) -> u64 {
        u64::MAX >> (8 * (8 - self.width))
    }

    /// Number `i`, read as one word (the run keeps 8 bytes spare).
    pub(crate) fn get(&self, i: usize) -> u64 {
        let at = i * self.width;
        u64::from_le_bytes(self.pages[at..at + 8].try_into().expect("eight bytes")) & self.mask()
    }

    pub(crate) fn set(&mut self, i: usize, v: u64) {
        let (at, mask) = (i * self.width, self.mask());
        let word = &mut self.pages[at..at + 8];
        let old = u64::from_le_bytes(word.try_into().expect("eight bytes"));
        word.copy_from_slice(&(old & !mask | v & mask).to_le_bytes());
    }

    pub(crate) fn push(&mut self, v: u64) {
        if (self.len + 1) * self.width + 8 > self.pages.len() {
            // Mapped pages cost nothing until written, so doubling is free.
            self.pages.resize((2 * self.pages.len()).max(1 << 16));
        }
        self.len += 1;
        self.set(self.len - 1, v);
    }

    pub(crate) fn last(&self) -> Option<u64> {
        self.len.checked_sub(1).map(|i| self.get(i))
    }

    pub(crate) fn pop(&mut self) -> Option<u64> {
        let v = self.last()?;
        self.len -= 1;
        Some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers of every width keep their value and their neighbours' as
    /// the stack grows past its first mapping, is set into, and shrinks.
    #[test]
    fn a_stack_keeps_its_numbers_through_growth() {
        for width in 1..=8 {
            let mask = u64::MAX >> (8 * (8 - width));
            let value = |i: u64| i.wrapping_mul(0x9e37_79b9_7f4a_7c15) & mask;
            let mut stack = Stack::new(width);
            let n = 100_000u64;
            for i in 0..n {
                stack.push(value(i));
            }
            for i in (0..n).step_by(7) {
                stack.set(i as usize, value(i + 1));
            }
            for i in (0..n).rev() {
                let want = if i % 7 == 0 { value(i + 1) } else { value(i) };
                assert_eq!(stack.pop(), Some(want), "width {width}, number {i}");
            }
            assert_eq!(stack.pop(), None);
            assert_eq!(stack.len(), 0);
        }
    }
}
