//! Where work runs: the `device=` argument of every call ("cpu", "gpu" or "auto") and the one rule that resolves it.
//! "auto" takes a hardware GPU (not a CPU adapter such as Mesa's lavapipe) when the work runs there and its result is
//! float32 anyway (float32 inputs to `eval`, `sample` and `pdf`; every render), so that "auto" never lowers the
//! precision a call would have on the CPU; otherwise the CPU.

use crate::error::{value_error, Error, Result};

/// The values of `device=`.
pub const DEVICES: [&str; 3] = ["cpu", "gpu", "auto"];

/// Whether `device` means the GPU for work that the GPU refuses for `refusal()`'s reason (None: it takes the work;
/// gpu::refusal for the models) and whose result is float32 anyway when `float32`: "cpu" never; "gpu" always, or an
/// error saying why not (no adapter: a Device error, the refusal: a ValueError); "auto" as the module says.
pub fn choose(device: &str, refusal: impl FnOnce() -> Option<String>, float32: bool) -> Result<bool> {
    match device {
        "cpu" => Ok(false),
        "gpu" => match (adapter(), refusal()) {
            (Err(why), _) => Err(Error::Device(format!("device='gpu': {why}"))),
            (Ok(_), Some(why)) => value_error(why),
            (Ok(_), None) => Ok(true),
        },
        "auto" => Ok(float32 && adapter().is_ok_and(|hardware| hardware) && refusal().is_none()),
        _ => value_error(format!("device must be one of {DEVICES:?}, got {device:?}")),
    }
}

/// Whether the process's GPU adapter is hardware (not a CPU adapter), or why there is none.
fn adapter() -> std::result::Result<bool, String> {
    #[cfg(feature = "gpu")]
    return crate::gpu::gpu().map(|g| g.info.device_type != wgpu::DeviceType::Cpu).map_err(|e| e.to_string());
    #[cfg(not(feature = "gpu"))]
    Err("this build of lamina has no GPU path (built without the 'gpu' feature)".into())
}
