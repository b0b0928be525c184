//! Cache hints: asks the CPU to start bringing a value's cache line in, with no effect on
//! any result. A batch of worlds (the Python package's) steps one world while the memory
//! of the next is on its way ([`crate::World::prefetch`]).

/// Starts loading the cache line that holds the start of `value` (a hint; nothing on
/// targets without one).
#[inline(always)]
pub fn line<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    safe_arch::prefetch_t0(value);
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// [`line`] for every cache line of `items` (up to `max` lines).
#[inline(always)]
pub fn lines<T>(items: &[T], max: usize) {
    let step = (64 / std::mem::size_of::<T>().max(1)).max(1);
    for item in items.iter().step_by(step).take(max) {
        line(item);
    }
}
