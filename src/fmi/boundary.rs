//! The C boundary: opaque handles, checked pointer helpers, and the
//! wrappers every exported function body runs in. A panic never crosses into
//! C (since Rust 1.81 it would abort the master): in an FMI function it
//! becomes fmi2Error and puts the instance in the error state
//! ([`with_instance`]); in the functions beyond FMI, which have no
//! instance, an error status with the panic's message ([`catch`]).

use super::instance::Instance;
use super::lifecycle::States;
use super::logger::Category;
use super::status::{Fault, Outcome, Status};
use fmi_sys::fmi2::{fmi2Component, fmi2FMUstate, fmi2Status};
use std::ffi::{c_char, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};

const INSTANCE_MAGIC: u64 = u64::from_le_bytes(*b"SSMinst\0");
const STATE_MAGIC: u64 = u64::from_le_bytes(*b"SSMstat\0");

/// What an `fmi2Component` points to. The magic number (first field) tells
/// an instance from other pointers a confused master may pass.
#[repr(C)]
struct InstanceHandle {
    magic: u64,
    instance: Instance,
}

/// What an `fmi2FMUstate` points to: the serialized state.
#[repr(C)]
pub(crate) struct StateHandle {
    magic: u64,
    pub(crate) bytes: Vec<u8>,
}

/// Runs `f`; a panic becomes `fallback`.
pub(crate) fn guard<T>(fallback: T, f: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(fallback)
}

pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("panic")
}

/// Hands `instance` to C.
pub(crate) fn into_component(instance: Instance) -> fmi2Component {
    Box::into_raw(Box::new(InstanceHandle { magic: INSTANCE_MAGIC, instance })).cast()
}

/// Reads the magic number at `p` if `p` can hold one.
///
/// # Safety
/// `p` is null or points to at least 8 readable bytes.
unsafe fn magic_at<T>(p: *const T) -> Option<u64> {
    let p = p.cast::<u64>();
    // SAFETY: non-null and aligned; readable by the caller's contract.
    (!p.is_null() && p.is_aligned()).then(|| unsafe { p.read() })
}

/// The instance behind `c`, if `c` is one.
///
/// # Safety
/// `c` is null or a pointer the master got from fmi2Instantiate and has not
/// freed (anything else that is readable is recognized by its magic number).
unsafe fn handle<'a>(c: fmi2Component) -> Option<&'a mut InstanceHandle> {
    let h = c.cast::<InstanceHandle>();
    // SAFETY: the magic number says `h` is a live handle made by into_component.
    (unsafe { magic_at(h) } == Some(INSTANCE_MAGIC)).then(|| unsafe { &mut *h })
}

/// fmi2FreeInstance: frees the instance behind `c`; null is accepted.
///
/// # Safety
/// As for [`handle`]; `c` is not used again.
pub(crate) unsafe fn free_component(c: fmi2Component) {
    // SAFETY: see the function's contract.
    if let Some(h) = unsafe { handle(c) } {
        h.magic = 0;
        // SAFETY: `h` came from Box::into_raw in into_component.
        drop(unsafe { Box::from_raw(std::ptr::from_mut(h)) });
    }
}

/// Runs `body` on the instance behind `c` if the instance's state is in
/// `allowed` ("illegal call sequence" otherwise), logs a failure as
/// "`function`: message" in the category of its status, and turns a panic
/// into fmi2Error and the error state.
///
/// # Safety
/// As for [`handle`].
pub(crate) unsafe fn with_instance(
    c: fmi2Component,
    function: &'static str,
    allowed: States,
    body: impl FnOnce(&mut Instance) -> Outcome,
) -> fmi2Status {
    // SAFETY: see the function's contract. Without an instance there is no
    // logger to tell.
    let Some(handle) = (unsafe { handle(c) }) else { return Status::Error.to_fmi() };
    let instance = &mut handle.instance;
    let run = catch_unwind(AssertUnwindSafe(|| match instance.check_state(allowed).and_then(|()| body(instance)) {
        Ok(status) => status,
        Err(fault) => {
            let message = format!("{function}: {}", fault.message);
            instance.logger.log(fault.status, Category::of_status(fault.status), &message);
            fault.status
        }
    }));
    match run {
        Ok(status) => status.to_fmi(),
        Err(payload) => {
            let reason = panic_message(payload.as_ref());
            guard((), || instance.fail(function, reason));
            Status::Error.to_fmi()
        }
    }
}

/// Hands an FMU state to C.
pub(crate) fn into_state(bytes: Vec<u8>) -> fmi2FMUstate {
    Box::into_raw(Box::new(StateHandle { magic: STATE_MAGIC, bytes })).cast()
}

/// The FMU state behind `s`.
///
/// # Safety
/// `s` is null or a pointer from fmi2GetFMUstate / fmi2DeSerializeFMUstate
/// that was not freed.
pub(crate) unsafe fn state<'a>(s: fmi2FMUstate) -> Result<&'a mut StateHandle, Fault> {
    let h = s.cast::<StateHandle>();
    if h.is_null() {
        return Err(Fault::error("the FMU state is NULL"));
    }
    if !h.is_aligned() {
        // Never read: a handle this FMU made lies on its type's alignment.
        return Err(Fault::error(format!(
            "the FMU state {h:p} is misaligned (not aligned to {} bytes): not a pointer this FMU returned",
            std::mem::align_of::<StateHandle>()
        )));
    }
    // SAFETY: see the function's contract; the magic number says `h` is a
    // live handle made by into_state.
    match unsafe { magic_at(h) } {
        Some(STATE_MAGIC) => Ok(unsafe { &mut *h }),
        _ => Err(Fault::error(format!(
            "the pointer {h:p} is not a live FMU state of this FMU: freed already, or never returned as one"
        ))),
    }
}

/// Frees the FMU state behind `s` and nulls the master's pointer.
///
/// # Safety
/// As for [`state`].
pub(crate) unsafe fn free_state(s: &mut fmi2FMUstate) -> Result<(), Fault> {
    if s.is_null() {
        return Ok(());
    }
    // SAFETY: see the function's contract.
    let h = unsafe { state(*s) }?;
    h.magic = 0;
    // SAFETY: `h` came from Box::into_raw in into_state.
    drop(unsafe { Box::from_raw(std::ptr::from_mut(h)) });
    *s = std::ptr::null_mut();
    Ok(())
}

fn check_pointer<T>(p: *const T, len: usize, what: &str) -> Result<(), Fault> {
    if p.is_null() {
        return Err(Fault::error(format!("`{what}` is NULL but has {len} elements")));
    }
    if !p.is_aligned() {
        return Err(Fault::error(format!("`{what}` is not aligned for its type")));
    }
    if len.checked_mul(size_of::<T>()).is_none_or(|bytes| bytes > isize::MAX as usize) {
        return Err(Fault::error(format!("`{what}` cannot have {len} elements")));
    }
    Ok(())
}

/// The array `p[0..len]`; with `len` = 0 the pointer is not looked at.
///
/// # Safety
/// `p` is null or points to `len` initialized elements that nothing writes
/// during the call.
pub(crate) unsafe fn slice<'a, T>(p: *const T, len: usize, what: &str) -> Result<&'a [T], Fault> {
    if len == 0 {
        return Ok(&[]);
    }
    check_pointer(p, len, what)?;
    // SAFETY: checked non-null, aligned, size in range; valid by contract.
    Ok(unsafe { std::slice::from_raw_parts(p, len) })
}

/// The writable array `p[0..len]`; with `len` = 0 the pointer is not looked at.
///
/// # Safety
/// `p` is null or points to `len` writable elements nothing else accesses
/// during the call.
pub(crate) unsafe fn slice_mut<'a, T>(p: *mut T, len: usize, what: &str) -> Result<&'a mut [T], Fault> {
    if len == 0 {
        return Ok(&mut []);
    }
    check_pointer(p, len, what)?;
    // SAFETY: checked non-null, aligned, size in range; valid by contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, len) })
}

/// The output argument `*p`.
///
/// # Safety
/// As for [`slice_mut`] with one element.
pub(crate) unsafe fn out<'a, T>(p: *mut T, what: &str) -> Result<&'a mut T, Fault> {
    // SAFETY: see the function's contract.
    Ok(&mut unsafe { slice_mut(p, 1, what) }?[0])
}

/// The NUL-terminated UTF-8 string at `p`.
///
/// # Safety
/// `p` is null or points to a NUL-terminated string.
pub(crate) unsafe fn text<'a>(p: *const c_char, what: &str) -> Result<&'a str, Fault> {
    if p.is_null() {
        return Err(Fault::error(format!("`{what}` is NULL")));
    }
    // SAFETY: non-null and NUL-terminated by contract.
    unsafe { CStr::from_ptr(p) }.to_str().map_err(|_| Fault::error(format!("`{what}` is not UTF-8")))
}

/// Runs `body`, an exported function that has no instance (the library's
/// functions beyond FMI 2.0): a panic becomes an error with its message.
pub(crate) fn catch(body: impl FnOnce() -> Result<(), Fault>) -> Result<(), Fault> {
    catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|payload| {
        Err(Fault::error(format!("internal error (please report): {}", panic_message(payload.as_ref()))))
    })
}

/// Writes `message` NUL-terminated into the caller's buffer `p[0..size]`,
/// cut at a character boundary where it does not fit; with `size` = 0
/// nothing is written and the pointer is not looked at.
///
/// # Safety
/// As for [`slice_mut`] with `size` bytes.
pub(crate) unsafe fn write_text(p: *mut c_char, size: usize, message: &str, what: &str) -> Result<(), Fault> {
    // SAFETY: see the function's contract.
    let bytes = unsafe { slice_mut(p.cast::<u8>(), size, what) }?;
    if bytes.is_empty() {
        return Ok(());
    }
    let mut cut = message.len().min(bytes.len() - 1);
    while !message.is_char_boundary(cut) {
        cut -= 1;
    }
    bytes[..cut].copy_from_slice(&message.as_bytes()[..cut]);
    bytes[cut] = 0;
    Ok(())
}
