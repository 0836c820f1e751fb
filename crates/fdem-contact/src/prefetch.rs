//! Software prefetch: asking the memory system for an element a loop will read a few
//! iterations later. The contact passes read arrays at indices that come from the broad
//! phase (faces and nodes of other bodies, anywhere in memory); without a hint each such
//! read waits for a cache miss. A hint changes no value: it reads nothing the program
//! sees and never faults.

/// Asks for `items[i]` to be brought into the cache; an index out of range asks for
/// nothing. A no-op off x86-64.
#[inline(always)]
pub(crate) fn prefetch<T>(items: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(item) = items.get(i) {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: a prefetch never faults and reads nothing the program sees; the pointer
        // is a reference into `items`.
        #[allow(unused_unsafe)]
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(item).cast::<i8>())
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (items, i);
}
