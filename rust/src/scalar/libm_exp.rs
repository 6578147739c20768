//! e^x for one run: the C library's own `exp`, called without its errno wrapper.
//!
//! A scalar RK4 stage of the paper's arm takes e^x twice (joint friction's tanh, eq. 1), so
//! fig. 14's run makes 800 000 calls. On glibc, `exp` (`exp@@GLIBC_2.29`) is a wrapper: it
//! calls the implementation through libm's PLT, then tests the result to set `errno` on
//! overflow or underflow. Nothing here reads `errno`, so the implementation is called
//! directly through glibc's exported alias for it, `__exp_finite` (kept as a versioned
//! symbol, `GLIBC_2.15`, since glibc 2.31; CPU dispatch by ifunc, resolved on lookup). It is
//! the same function the wrapper calls, so every bit is `f64::exp`'s (tested below,
//! specials included); docs/performance-history.md §32 has what it saves.
//!
//! Where the symbol is not found (another C library, another platform), `f64::exp` is used.

use std::sync::atomic::{AtomicPtr, Ordering};

type ExpFn = extern "C" fn(f64) -> f64;

/// The function `exp` calls: first `resolve`, which looks the implementation up once and
/// puts it here. So a call is one load and one indirect call, with no branch or cold path
/// inlined where it is used (a `OnceLock` there cost a Panda run, which never calls it,
/// 2.5 %: docs/performance-history.md §32).
static IMPLEMENTATION: AtomicPtr<()> = AtomicPtr::new(resolve as ExpFn as *mut ());

/// e^x with `f64::exp`'s bits.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    let address = IMPLEMENTATION.load(Ordering::Relaxed);
    // SAFETY: the static only ever holds an `ExpFn`: `resolve`, `rust_exp` or glibc's
    // `double __exp_finite(double)`.
    let f = unsafe { std::mem::transmute::<*mut (), ExpFn>(address) };
    f(x)
}

/// The first call: find the implementation, keep it for every later call, and use it.
/// Racing threads store the same value.
extern "C" fn resolve(x: f64) -> f64 {
    let f = find().unwrap_or(rust_exp as ExpFn);
    IMPLEMENTATION.store(f as *mut (), Ordering::Relaxed);
    f(x)
}

/// Rust's own `f64::exp`, where glibc's implementation is not found.
extern "C" fn rust_exp(x: f64) -> f64 {
    x.exp()
}

/// glibc's `__exp_finite@GLIBC_2.15`, if this process has it, and if it is `exp`.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn find() -> Option<ExpFn> {
    // libm is loaded (this library links it), but maybe not in the global scope (a Python
    // extension is loaded RTLD_LOCAL): ask for its handle, then the default scope.
    // SAFETY: dlopen/dlvsym with NUL-terminated names; RTLD_NOLOAD never loads anything.
    let address = unsafe {
        let libm = libc::dlopen(c"libm.so.6".as_ptr(), libc::RTLD_LAZY | libc::RTLD_NOLOAD);
        let scope = if libm.is_null() {
            libc::RTLD_DEFAULT
        } else {
            libm
        };
        libc::dlvsym(scope, c"__exp_finite".as_ptr(), c"GLIBC_2.15".as_ptr())
    };
    if address.is_null() {
        return None;
    }
    // SAFETY: the address of glibc's `double __exp_finite(double)` (an ifunc, resolved by
    // the lookup to this CPU's implementation), cast to that signature.
    let f = unsafe { std::mem::transmute::<*mut libc::c_void, ExpFn>(address) };
    // Trust it only if it is `exp`: a handful of values, bit for bit.
    let agrees = [0.0, -1.0, 0.5, -700.0, 1e-300, -37.5]
        .iter()
        .all(|&x| f(x).to_bits() == x.exp().to_bits());
    agrees.then_some(f)
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn find() -> Option<ExpFn> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_direct_call_is_f64_exp_bit_for_bit() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            709.78,
            709.79,
            -745.13,
            -745.14,
            -708.4,
            1e-310,
            -1e-310,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for x in specials {
            assert_eq!(exp(x).to_bits(), x.exp().to_bits(), "x = {x:e}");
        }
        // The arguments joint friction gives it: −2|q̇|/ε over many decades, and a grid.
        let mut x = -1e-12;
        while x > -800.0 {
            assert_eq!(exp(x).to_bits(), x.exp().to_bits(), "x = {x:e}");
            x *= 1.0137;
        }
        for i in -200_000..200_000 {
            let x = f64::from(i) * 3.7e-3;
            assert_eq!(exp(x).to_bits(), x.exp().to_bits(), "x = {x:e}");
        }
    }

    #[cfg(all(target_os = "linux", target_env = "gnu", target_arch = "x86_64"))]
    #[test]
    fn glibc_s_implementation_is_found_on_linux() {
        // The speed-up is real only if the lookup succeeds where it is expected to.
        assert!(find().is_some());
        exp(1.0);
        let resolved = IMPLEMENTATION.load(Ordering::Relaxed);
        assert_ne!(resolved, resolve as ExpFn as *mut ());
        assert_ne!(resolved, rust_exp as ExpFn as *mut ());
    }
}
