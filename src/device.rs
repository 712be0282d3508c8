//! Where work runs: the `device=` argument of every call ("cpu", "gpu" or "auto", the default everywhere) and the one
//! rule that resolves it. "auto" takes a hardware GPU (not a CPU adapter such as Mesa's lavapipe) when the work runs
//! there and its result is float32 anyway (float32 inputs to `eval`, `sample` and `pdf`; every render), so that "auto"
//! never changes the dtype a call returns (the GPU's float32 arithmetic agrees with the CPU's to about 1e-5,
//! docs/conventions.md); otherwise the CPU.

use crate::error::{py, py_list, value_error, Error, Result};

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
        _ => value_error(format!("device must be one of {}, got {}", py_list(&DEVICES), py(device))),
    }
}

/// Whether the process's GPU adapter is hardware (not a CPU adapter), or why there is none.
fn adapter() -> std::result::Result<bool, String> {
    #[cfg(feature = "gpu")]
    return crate::gpu::gpu().map(|g| g.info.device_type != wgpu::DeviceType::Cpu).map_err(|e| e.to_string());
    #[cfg(not(feature = "gpu"))]
    Err("this build of lamina has no GPU path (built without the 'gpu' feature)".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rule_asks_only_what_it_needs() {
        let never = || -> Option<String> { panic!("the refusal is not asked here") };
        assert_eq!(choose("cpu", never, true), Ok(false));
        assert_eq!(choose("auto", never, false), Ok(false)); // a float64 result never leaves the CPU under "auto"
        assert!(matches!(choose("tpu", never, true), Err(Error::Value(m)) if m.contains("'tpu'")));
        // "gpu": the refusal as a ValueError, or without an adapter a Device error saying how to get one.
        match choose("gpu", || Some("model 'x' runs on the CPU only".into()), true) {
            Err(Error::Value(m)) => assert_eq!(m, "model 'x' runs on the CPU only"),
            Err(Error::Device(m)) => assert!(m.starts_with("device='gpu': "), "{m}"),
            other => panic!("{other:?}"),
        }
        // "auto" takes a CPU adapter (lavapipe) never, a refused model never.
        let hardware = adapter().unwrap_or(false);
        assert_eq!(choose("auto", || None, true), Ok(hardware));
        assert_eq!(choose("auto", || Some("no".into()), true), Ok(false));
    }
}
