//! The layer stack: dielectric layers (an interface and the homogeneous slab beneath it) top to bottom, ending
//! in one opaque base (conductor or diffuse). Optical constants are resolved per channel (RGB or wavelengths)
//! before they reach Rust; geometry (roughness, tangent angle, thickness) is shared by all channels.

use crate::error::{value_error, Result};
use crate::optics::distribution::{Distribution, Microfacet};

#[derive(Clone, Debug)]
pub enum Layer {
    /// Interface of absolute IOR `ior` over a slab of `thickness` with absorption `sigma_a`, scattering `sigma_s`
    /// (per unit length) and Henyey–Greenstein asymmetry `g`.
    Dielectric {
        ior: Vec<f64>,
        alpha: (f64, f64),
        angle: f64,
        thickness: f64,
        sigma_a: Vec<f64>,
        sigma_s: Vec<f64>,
        g: f64,
    },
    /// Opaque conductor of absolute complex IOR `ior` + i`k`.
    Conductor { ior: Vec<f64>, k: Vec<f64>, alpha: (f64, f64), angle: f64 },
    /// Opaque diffuse base: Lambert when `roughness` = 0, else Oren–Nayar with σ = `roughness` radians.
    Diffuse { albedo: Vec<f64>, roughness: f64 },
}

impl Layer {
    /// Checks the layer's parameters against their ranges and `channels` values per colour quantity; messages
    /// start with `what` (e.g. "layer 0 (Dielectric)").
    pub fn check(&self, what: &str, channels: usize) -> Result<()> {
        let p = |param: &str| format!("{what}: {param}");
        match self {
            Layer::Dielectric { ior, alpha, angle, thickness, sigma_a, sigma_s, g } => {
                check_channels(&p("ior"), ior, channels)?;
                check_range(&p("ior"), ior, 0.0, f64::INFINITY, true, "(0, inf)")?;
                check_range(&p("roughness"), &[alpha.0, alpha.1], 0.0, 1.0, false, "[0, 1]")?;
                check_range(&p("angle"), &[*angle], f64::MIN, f64::MAX, false, "(-inf, inf) (finite radians)")?;
                check_range(&p("thickness"), &[*thickness], 0.0, f64::MAX, false, "[0, inf)")?;
                check_channels(&p("sigma_a"), sigma_a, channels)?;
                check_range(&p("sigma_a"), sigma_a, 0.0, f64::MAX, false, "[0, inf)")?;
                check_channels(&p("sigma_s"), sigma_s, channels)?;
                check_range(&p("sigma_s"), sigma_s, 0.0, f64::MAX, false, "[0, inf)")?;
                check_range(&p("g"), &[*g], -1.0, 1.0, true, "(-1, 1)")?;
                if *g >= 1.0 {
                    return value_error(format!("{} must be in (-1, 1), got {g}", p("g")));
                }
            }
            Layer::Conductor { ior, k, alpha, angle } => {
                check_channels(&p("ior"), ior, channels)?;
                check_range(&p("ior"), ior, 0.0, f64::INFINITY, true, "(0, inf)")?;
                check_channels(&p("k"), k, channels)?;
                check_range(&p("k"), k, 0.0, f64::MAX, false, "[0, inf)")?;
                check_range(&p("roughness"), &[alpha.0, alpha.1], 0.0, 1.0, false, "[0, 1]")?;
                check_range(&p("angle"), &[*angle], f64::MIN, f64::MAX, false, "(-inf, inf) (finite radians)")?;
            }
            Layer::Diffuse { albedo, roughness } => {
                check_channels(&p("albedo"), albedo, channels)?;
                check_range(&p("albedo"), albedo, 0.0, 1.0, false, "[0, 1]")?;
                check_range(&p("roughness"), &[*roughness], 0.0, 1.0, false, "[0, 1]")?;
            }
        }
        Ok(())
    }

    pub fn name(&self) -> &'static str {
        match self {
            Layer::Dielectric { .. } => "Dielectric",
            Layer::Conductor { .. } => "Conductor",
            Layer::Diffuse { .. } => "Diffuse",
        }
    }

    pub fn is_opaque(&self) -> bool {
        !matches!(self, Layer::Dielectric { .. })
    }

    /// The microfacet distribution of the layer's interface (None for a diffuse base).
    pub fn microfacet(&self, dist: Distribution) -> Option<Microfacet> {
        match *self {
            Layer::Dielectric { alpha, angle, .. } | Layer::Conductor { alpha, angle, .. } => {
                Some(Microfacet::new(dist, alpha.0, alpha.1, angle))
            }
            Layer::Diffuse { .. } => None,
        }
    }
}

/// A layer field that gradients are taken with respect to (`Field::NAMES`: their Python names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    Ior,
    K,
    RoughnessX,
    RoughnessY,
    Angle,
    Albedo,
    DiffuseRoughness,
    Thickness,
    SigmaA,
    SigmaS,
    G,
}

impl Field {
    pub const NAMES: [&'static str; 11] = [
        "ior",
        "k",
        "roughness_x",
        "roughness_y",
        "angle",
        "albedo",
        "diffuse_roughness",
        "thickness",
        "sigma_a",
        "sigma_s",
        "g",
    ];
    pub const ALL: [Field; 11] = [
        Field::Ior,
        Field::K,
        Field::RoughnessX,
        Field::RoughnessY,
        Field::Angle,
        Field::Albedo,
        Field::DiffuseRoughness,
        Field::Thickness,
        Field::SigmaA,
        Field::SigmaS,
        Field::G,
    ];

    /// The field's Python name.
    pub fn name(self) -> &'static str {
        Self::NAMES[Self::ALL.iter().position(|f| *f == self).unwrap_or(0)]
    }
}

impl std::str::FromStr for Field {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> Result<Self> {
        crate::error::parse_choice("field", s, &Self::NAMES, &Self::ALL)
    }
}

#[derive(Clone, Debug)]
pub struct Stack {
    pub layers: Vec<Layer>,
    /// Absolute IOR of the medium above the stack.
    pub ext_ior: f64,
    pub channels: usize,
}

fn check_range(what: &str, values: &[f64], lo: f64, hi: f64, lo_open: bool, range: &str) -> Result<()> {
    for &v in values {
        let below = if lo_open { v <= lo } else { v < lo };
        if !v.is_finite() || below || v > hi {
            return value_error(format!("{what} must be in {range}, got {v}"));
        }
    }
    Ok(())
}

fn check_channels(what: &str, values: &[f64], channels: usize) -> Result<()> {
    if values.len() != channels {
        return value_error(format!("{what} has {} channels but the stack has {channels}", values.len()));
    }
    Ok(())
}

impl Stack {
    /// Validates a stack: at least one layer, exactly one opaque base at the bottom, parameters in range.
    pub fn new(layers: Vec<Layer>, ext_ior: f64) -> Result<Stack> {
        check_range("ext_ior", &[ext_ior], 0.0, f64::INFINITY, true, "(0, inf)")?;
        let Some(last) = layers.last() else {
            return value_error(
                "layers: a stack needs at least one layer and must end in an opaque base (Conductor or Diffuse)",
            );
        };
        if let Some(i) = layers[..layers.len() - 1].iter().position(|l| l.is_opaque()) {
            let name = layers[i].name();
            return value_error(format!("layer {i} ({name}) is opaque, so it must be the last layer"));
        }
        if !last.is_opaque() {
            return value_error("layers: the stack has no opaque base; its last layer must be a Conductor or Diffuse");
        }
        let channels = match last {
            Layer::Conductor { ior, .. } => ior.len(),
            Layer::Diffuse { albedo, .. } => albedo.len(),
            Layer::Dielectric { .. } => unreachable!(),
        };
        for (i, layer) in layers.iter().enumerate() {
            if layer.is_opaque() && i + 1 != layers.len() {
                return value_error(format!("layer {i} ({}) is opaque, so it must be the last layer", layer.name()));
            }
            layer.check(&format!("layer {i} ({})", layer.name()), channels)?;
        }
        Ok(Stack { layers, ext_ior, channels })
    }
}

/// A layer as the models see it: its optical constants relative to the medium directly above it (per channel).
pub struct Relative {
    /// η = n_layer / n_above (dielectrics and conductors); for a diffuse base, n_above / n_outside.
    pub eta: Vec<f64>,
    /// κ / n_above (conductors; 0 otherwise).
    pub kappa: Vec<f64>,
}

impl Stack {
    /// Every layer's IOR and κ relative to the medium above it, top to bottom (the one place they are computed).
    pub fn interfaces(&self) -> Vec<Relative> {
        let mut above = vec![self.ext_ior; self.channels];
        let zero = vec![0.0; self.channels];
        let over = |v: &[f64], above: &[f64]| v.iter().zip(above).map(|(x, a)| x / a).collect::<Vec<f64>>();
        self.layers
            .iter()
            .map(|layer| match layer {
                Layer::Dielectric { ior, .. } => {
                    let r = Relative { eta: over(ior, &above), kappa: zero.clone() };
                    above = ior.clone();
                    r
                }
                Layer::Conductor { ior, k, .. } => Relative { eta: over(ior, &above), kappa: over(k, &above) },
                Layer::Diffuse { .. } => {
                    Relative { eta: above.iter().map(|a| a / self.ext_ior).collect(), kappa: zero.clone() }
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gold() -> Layer {
        Layer::Conductor { ior: vec![0.2, 0.4, 1.4], k: vec![3.6, 2.5, 1.9], alpha: (0.2, 0.2), angle: 0.0 }
    }

    fn coat(roughness: f64) -> Layer {
        Layer::Dielectric {
            ior: vec![1.5; 3],
            alpha: (roughness, roughness),
            angle: 0.0,
            thickness: 0.0,
            sigma_a: vec![0.0; 3],
            sigma_s: vec![0.0; 3],
            g: 0.0,
        }
    }

    #[test]
    fn validation_names_the_parameter() {
        assert!(Stack::new(vec![coat(0.1), gold()], 1.0).is_ok());
        let msg = |r: Result<Stack>| r.unwrap_err().to_string();
        assert!(msg(Stack::new(vec![], 1.0)).contains("at least one layer"));
        assert!(msg(Stack::new(vec![coat(0.1)], 1.0)).contains("no opaque base"));
        assert!(msg(Stack::new(vec![gold(), coat(0.1)], 1.0))
            .contains("layer 0 (Conductor) is opaque, so it must be the last"));
        assert!(
            msg(Stack::new(vec![coat(1.5), gold()], 1.0)).contains("layer 0 (Dielectric): roughness must be in [0, 1]")
        );
        assert!(msg(Stack::new(vec![gold()], 0.0)).contains("ext_ior"));
        let bad = Layer::Conductor { ior: vec![0.0, 1.0, 1.0], k: vec![1.0; 3], alpha: (0.1, 0.1), angle: 0.0 };
        assert!(msg(Stack::new(vec![bad], 1.0)).contains("ior must be in (0, inf)"));
    }
}
