//! Model options: one typed struct for all models, filled from each model's option table (name, default, allowed
//! values or range, one-line doc). A model accepts exactly the options its table lists; the table is what
//! `lamina.models()`, `Stack.eval`'s docstring and the README show.

use super::belcour::{Tir, Variant};
use crate::error::{type_error, value_error, Result};
use crate::optics::distribution::{Distribution, G2Form};
use crate::optics::fresnel::FresnelForm;

/// What values an option takes, and its default.
#[derive(Clone, Copy, Debug)]
pub enum OptionKind {
    /// One of the listed strings.
    Choice { choices: &'static [&'static str], default: &'static str },
    /// True or false.
    Flag { default: bool },
    /// A number in [lo, hi].
    Number { lo: f64, hi: f64, default: f64 },
    /// One number per channel (or one for all), each in [lo, hi].
    Channels { lo: f64, hi: f64, default: f64 },
}

/// One option of a model.
#[derive(Clone, Copy, Debug)]
pub struct OptionSpec {
    pub name: &'static str,
    pub kind: OptionKind,
    pub doc: &'static str,
}

/// An option's value as the caller gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Text(String),
    Flag(bool),
    Number(f64),
    List(Vec<f64>),
}

/// Every model's options. Fields a model does not list keep their defaults and are not read by it.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    pub distribution: Distribution,
    pub g2: G2Form,
    pub fresnel: FresnelForm,
    /// Belcour's symmetric (reciprocal) variant: statistics at |wo·h| instead of cos θo.
    pub symmetric: bool,
    /// Belcour 2018 choices where the paper and the reference code differ (see models/belcour).
    pub belcour: Variant,
    /// Belcour 2018: interpolate the adding-doubling from a table built when the model is prepared.
    pub belcour_table: bool,
    /// Steinberg: the fitted closed forms instead of the tabulated integrals.
    pub steinberg_fitted: bool,
    /// Weidlich–Wilkie / Elek: Elek's precomputed Fresnel and Beckmann tables.
    pub elek_precomputed: bool,
    /// Single-pass models: each layer at least as rough as the one above (Elek's m₂ ≥ m₁).
    pub clamp_roughness: bool,
    /// Single-pass models: the radiance compression 1/η² through each dielectric interface.
    pub eta2: bool,
    /// Single-pass models: the geometric series of inter-reflections between a diffuse base and the coat above it.
    pub interreflection: bool,
    /// Single-pass models: the inter-reflections between a conductor base and the coat above it.
    pub conductor_interreflection: bool,
    /// Belcour, Steinberg: rough interfaces transmit what single-scattering microfacets do (tables::steinberg's T).
    pub microfacet_transmission: bool,
    /// Belcour, Steinberg, Weidlich–Wilkie: f ← s f + a fitted over the azimuth to the adding-doubling solution.
    pub transport_fit: bool,
    /// Elek's patina (with the per-element input `mask`): smoothstep centre and half-width, and the tarnish of the
    /// base under the patina per channel.
    pub extent: f64,
    pub transition: f64,
    pub tint: Vec<f64>,
    /// Albedo scaling: (1 − E(μi))(1 − E(μo)) (reciprocal) instead of 1 − E(μo).
    pub scaling_reciprocal: bool,
    /// Albedo scaling: OpenPBR's roughening of each layer under a rough one.
    pub roughening: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            distribution: Distribution::Ggx,
            g2: G2Form::HeightCorrelated,
            fresnel: FresnelForm::Exact,
            symmetric: false,
            belcour: Variant::default(),
            belcour_table: true,
            steinberg_fitted: false,
            elek_precomputed: false,
            clamp_roughness: true,
            eta2: true,
            interreflection: false,
            microfacet_transmission: false,
            conductor_interreflection: false,
            transport_fit: false,
            extent: 0.5,
            transition: 0.1,
            tint: vec![1.0],
            scaling_reciprocal: true,
            roughening: true,
        }
    }
}

/// A choice among strings.
pub const fn choice(
    name: &'static str,
    choices: &'static [&'static str],
    default: &'static str,
    doc: &'static str,
) -> OptionSpec {
    OptionSpec { name, kind: OptionKind::Choice { choices, default }, doc }
}

/// A flag.
pub const fn flag(name: &'static str, default: bool, doc: &'static str) -> OptionSpec {
    OptionSpec { name, kind: OptionKind::Flag { default }, doc }
}

pub const DISTRIBUTIONS: &[&str] = &["ggx", "beckmann"];
pub const G2_FORMS: &[&str] = &["height_correlated", "separable", "v_cavity"];
pub const DISTRIBUTION: OptionSpec = choice("distribution", DISTRIBUTIONS, "ggx", "microfacet distribution");
pub const G2: OptionSpec = choice(
    "g2",
    G2_FORMS,
    "height_correlated",
    "masking-shadowing: Smith (height-correlated or separable, as Mitsuba 3) or V-cavity",
);
pub const FRESNEL: OptionSpec = choice(
    "fresnel",
    &["exact", "schlick", "lazanyi"],
    "exact",
    "Fresnel form: exact, Schlick, or Lazányi–Szirmay-Kalos",
);
pub const CLAMP_ROUGHNESS: OptionSpec = flag(
    "clamp_roughness",
    true,
    "each layer at least as rough as the one above (Elek's m₂ ≥ m₁); False: published form",
);
pub const ETA2: OptionSpec =
    flag("eta2", true, "radiance compression 1/η² through each coat (lamina's addition); False: published form");
pub const INTERREFLECTION: OptionSpec = flag(
    "interreflection",
    false,
    "lamina's correction: inter-reflections between a diffuse base and the coat above, 1/(1 − ρ r) in closed form",
);

pub const CONDUCTOR_INTERREFLECTION: OptionSpec = flag(
    "conductor_interreflection",
    false,
    "lamina's correction: inter-reflections between a conductor base and the coat above (what the coat reflects back \
     down, total internal reflection included, returns diffusely)",
);
pub const MICROFACET_TRANSMISSION: OptionSpec = flag(
    "microfacet_transmission",
    false,
    "lamina's correction: rough interfaces transmit what single-scattering microfacets do (masking included, \
     lamina's table) instead of 1 − R or the mean Fresnel transmission",
);

pub const TRANSPORT_FIT: OptionSpec = flag(
    "transport_fit",
    false,
    "lamina's correction: at each (θi, θo), f ← s f + a fitted over the azimuth to the stack's adding-doubling \
     solution (its mean exact: the light the model misses added, its lobes' energy set); isotropic stacks, CPU only",
);

/// `variant`: "published" (the default) or "improved", which switches on the corrections that `improved` lists
/// for the model; options given beside it still override them.
pub const fn variant(improved: &'static str) -> OptionSpec {
    OptionSpec {
        name: "variant",
        kind: OptionKind::Choice { choices: &["published", "improved"], default: "published" },
        doc: improved,
    }
}

/// The corrections (flags) that `variant="improved"` switches on, per model: each chosen by its measured effect
/// (docs/validation.md, "lamina's corrections, one at a time").
pub fn improved(model: &str) -> &'static [&'static str] {
    match model {
        "belcour" | "steinberg" | "weidlich_wilkie" => &["transport_fit"],
        _ => &[],
    }
}

/// Parses an option's value against its kind: a string of the choices, a bool, or numbers in range.
fn check(spec: &OptionSpec, value: &Value) -> Result<()> {
    let name = spec.name;
    match (spec.kind, value) {
        (OptionKind::Choice { choices, .. }, Value::Text(v)) if choices.contains(&v.as_str()) => Ok(()),
        (OptionKind::Choice { choices, .. }, Value::Text(v)) => {
            value_error(format!("{name} must be one of {choices:?}, got {v:?}"))
        }
        (OptionKind::Choice { .. }, _) => type_error(format!("{name} must be a string")),
        (OptionKind::Flag { .. }, Value::Flag(_)) => Ok(()),
        (OptionKind::Flag { .. }, _) => type_error(format!("{name} must be a bool")),
        (OptionKind::Number { lo, hi, .. }, Value::Number(x))
        | (OptionKind::Channels { lo, hi, .. }, Value::Number(x)) => {
            if (lo..=hi).contains(x) {
                Ok(())
            } else {
                value_error(format!("{name} must be in [{lo}, {hi}], got {x}"))
            }
        }
        (OptionKind::Channels { lo, hi, .. }, Value::List(v)) => match v.iter().find(|x| !(lo..=hi).contains(*x)) {
            _ if v.is_empty() => value_error(format!("{name} must hold at least one value")),
            Some(x) => value_error(format!("{name} must be in [{lo}, {hi}], got {x}")),
            None => Ok(()),
        },
        (OptionKind::Number { .. }, _) => type_error(format!("{name} must be a number")),
        (OptionKind::Channels { .. }, _) => type_error(format!("{name} must be a number or one number per channel")),
    }
}

impl Options {
    /// The options of a model: the defaults of its table, then `given` (each validated against the table); an
    /// option the model does not take is a TypeError that lists the ones it does.
    pub fn parse(model: &str, specs: &[OptionSpec], given: &[(String, Value)]) -> Result<Options> {
        let mut o = Options::default();
        for spec in specs {
            let default = match spec.kind {
                OptionKind::Choice { default, .. } => Value::Text(default.into()),
                OptionKind::Flag { default } => Value::Flag(default),
                OptionKind::Number { default, .. } => Value::Number(default),
                OptionKind::Channels { default, .. } => Value::List(vec![default]),
            };
            o.set(spec.name, &default);
        }
        let improved_variant = given.iter().any(|(k, v)| k == "variant" && *v == Value::Text("improved".into()));
        if improved_variant && specs.iter().any(|s| s.name == "variant") {
            improved(model).iter().for_each(|name| o.set(name, &Value::Flag(true)));
        }
        for (key, value) in given {
            let Some(spec) = specs.iter().find(|s| s.name == key) else {
                let names: Vec<&str> = specs.iter().map(|s| s.name).collect();
                return type_error(format!("model {model:?} has no option {key:?}; its options are {names:?}"));
            };
            check(spec, value)?;
            o.set(key, value);
        }
        Ok(o)
    }

    /// Sets one (checked) option.
    fn set(&mut self, key: &str, value: &Value) {
        let text = || match value {
            Value::Text(s) => s.as_str(),
            _ => "",
        };
        let flag = matches!(value, Value::Flag(true));
        let number = match value {
            Value::Number(x) => *x,
            _ => 0.0,
        };
        match key {
            "distribution" => {
                self.distribution = if text() == "beckmann" { Distribution::Beckmann } else { Distribution::Ggx }
            }
            "g2" => {
                self.g2 = match text() {
                    "separable" => G2Form::Separable,
                    "v_cavity" => G2Form::VCavity,
                    _ => G2Form::HeightCorrelated,
                }
            }
            "fresnel" => {
                self.fresnel = match text() {
                    "schlick" => FresnelForm::Schlick,
                    "lazanyi" => FresnelForm::Lazanyi,
                    _ => FresnelForm::Exact,
                }
            }
            "symmetric" => self.symmetric = flag,
            "cosines" => self.belcour.real_cosines = text() == "real",
            "jacobian" => self.belcour.jacobian_j21 = text() == "j21",
            "energy" => self.belcour.fresnel_energy = text() == "fresnel",
            "tir" => {
                self.belcour.tir = match text() {
                    "transmittance" => Tir::Transmittance,
                    "fraction" => Tir::Fraction,
                    _ => Tir::Off,
                }
            }
            "tabulated" => self.belcour_table = flag,
            "lut" => self.steinberg_fitted = text() == "fitted",
            "precomputed" => self.elek_precomputed = flag,
            "clamp_roughness" => self.clamp_roughness = flag,
            "eta2" => self.eta2 = flag,
            "interreflection" => self.interreflection = flag,
            "microfacet_transmission" => self.microfacet_transmission = flag,
            "conductor_interreflection" => self.conductor_interreflection = flag,
            "transport_fit" => self.transport_fit = flag,
            "variant" => {} // its corrections are set in `parse`
            "scaling" => self.scaling_reciprocal = text() == "reciprocal",
            "roughening" => self.roughening = flag,
            "extent" => self.extent = number,
            "transition" => self.transition = number,
            "tint" => {
                self.tint = match value {
                    Value::List(v) => v.clone(),
                    _ => vec![number],
                }
            }
            _ => unreachable!("option {key} is in a model's table but has no field"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_option_of_every_model_parses_its_default_and_rejects_other_models_options() {
        for info in super::super::CATALOGUE {
            assert!(info.inputs.len() <= super::super::MAX_INPUTS, "{}", info.name);
            let o = Options::parse(info.name, info.options, &[]).unwrap();
            assert_eq!(o, Options::parse(info.name, info.options, &[]).unwrap());
            let err = Options::parse(info.name, info.options, &[("nope".into(), Value::Flag(true))]).unwrap_err();
            assert!(err.to_string().contains("has no option \"nope\""), "{err}");
        }
    }

    #[test]
    fn the_improved_variant_sets_its_corrections_and_given_options_override_them() {
        let text = Value::Text("improved".into());
        for info in super::super::CATALOGUE.iter().filter(|i| i.options.iter().any(|s| s.name == "variant")) {
            let names: Vec<&str> = info.options.iter().map(|s| s.name).collect();
            assert!(!improved(info.name).is_empty(), "{}", info.name);
            for name in improved(info.name) {
                assert!(names.contains(name), "{}: {name}", info.name);
                let on = Options::parse(info.name, info.options, &[("variant".into(), text.clone())]).unwrap();
                let off = Options::parse(
                    info.name,
                    info.options,
                    &[("variant".into(), text.clone()), (name.to_string(), Value::Flag(false))],
                )
                .unwrap();
                assert_ne!(on, off, "{}: {name}", info.name);
            }
            let published = Options::parse(info.name, info.options, &[]).unwrap();
            let given = [("variant".into(), Value::Text("published".into()))];
            assert_eq!(published, Options::parse(info.name, info.options, &given).unwrap());
        }
    }
}
