//! Model options: each model declares its options as a table (name, kind with its default and allowed values or
//! range, one-line doc) in its catalogue entry, and reads them into its own `Options` struct from `Args`: the
//! given values, each checked against the table, with the table's defaults for the rest. The table is what
//! `lamina.models()`, `Stack.eval`'s docstring, the README and each model's `//!` parameter table show.

use crate::error::{py, py_list, type_error, value_error, Error, Result};
use crate::models::ModelInfo;
use crate::optics::distribution::{Distribution, G2Form};
use crate::optics::fresnel::FresnelForm;
use crate::transport::Microsurface;
use std::str::FromStr;

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
    /// `variant`: "published" (the default) or "improved", which switches on the listed corrections (flags of the
    /// same table); a correction given beside it still overrides it.
    Variant { improved: &'static [&'static str] },
}

/// The values of a `variant` option.
pub const VARIANTS: &[&str] = &["published", "improved"];

/// One option of a model.
#[derive(Clone, Copy, Debug)]
pub struct OptionSpec {
    pub name: &'static str,
    pub kind: OptionKind,
    pub doc: &'static str,
}

impl OptionSpec {
    /// The option's default value.
    pub fn default(&self) -> Value {
        match self.kind {
            OptionKind::Choice { default, .. } => Value::Text(default.into()),
            OptionKind::Flag { default } => Value::Flag(default),
            OptionKind::Number { default, .. } => Value::Number(default),
            OptionKind::Channels { default, .. } => Value::List(vec![default]),
            OptionKind::Variant { .. } => Value::Text(VARIANTS[0].into()),
        }
    }

    /// The allowed values, as a Python user writes them.
    pub fn choices(&self) -> Option<Vec<&'static str>> {
        match self.kind {
            OptionKind::Choice { choices, .. } => Some(choices.to_vec()),
            OptionKind::Variant { .. } => Some(VARIANTS.to_vec()),
            _ => None,
        }
    }

    /// Every value the option takes that is not its default: the other choices, the other flag value, the end of its
    /// range that is not the default.
    pub fn others(&self) -> Vec<Value> {
        match self.kind {
            OptionKind::Choice { choices, default } => {
                choices.iter().filter(|c| **c != default).map(|c| Value::Text(c.to_string())).collect()
            }
            OptionKind::Variant { .. } => vec![Value::Text(VARIANTS[1].into())],
            OptionKind::Flag { default } => vec![Value::Flag(!default)],
            OptionKind::Number { lo, hi, default } | OptionKind::Channels { lo, hi, default } => {
                vec![Value::Number(if default == lo { hi } else { lo })]
            }
        }
    }

    /// Checks a value against the option's kind: a string of the choices, a bool, or numbers in range.
    fn check(&self, value: &Value) -> Result<()> {
        let name = self.name;
        match (self.kind, value) {
            (OptionKind::Choice { .. } | OptionKind::Variant { .. }, Value::Text(v)) => {
                let choices = self.choices().unwrap_or_default();
                if choices.contains(&v.as_str()) {
                    Ok(())
                } else {
                    value_error(format!("{name} must be one of {}, got {}", py_list(&choices), py(v)))
                }
            }
            (OptionKind::Choice { .. } | OptionKind::Variant { .. }, _) => {
                type_error(format!("{name} must be a string"))
            }
            (OptionKind::Flag { .. }, Value::Flag(_)) => Ok(()),
            (OptionKind::Flag { .. }, _) => type_error(format!("{name} must be a bool")),
            (OptionKind::Number { lo, hi, .. } | OptionKind::Channels { lo, hi, .. }, Value::Number(x)) => {
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
            (OptionKind::Channels { .. }, _) => {
                type_error(format!("{name} must be a number or one number per channel"))
            }
        }
    }
}

/// An option's value as the caller gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Text(String),
    Flag(bool),
    Number(f64),
    List(Vec<f64>),
}

/// A model's options: every option of its table with its value, given or default, in the table's order. Equal
/// arguments print equally (Debug prints every f64 in its shortest round-trip form): `models::prepare` keys its
/// cache by them.
#[derive(Clone, Debug, PartialEq)]
pub struct Args {
    values: Vec<(&'static str, Value)>,
}

impl Args {
    /// The options of catalogue entry `info` from its table: the defaults, then `given`, each checked against the
    /// table; an option the model does not take is a TypeError that lists its options and per-element inputs (the one
    /// such check: Python asks it).
    pub fn parse(info: &ModelInfo, given: &[(String, Value)]) -> Result<Args> {
        let specs = info.options;
        let mut values = Args::defaults(specs).values;
        for (key, value) in given {
            let Some(k) = specs.iter().position(|s| s.name == key) else {
                let options: Vec<&str> = specs.iter().map(|s| s.name).collect();
                let inputs: Vec<&str> = info.inputs.iter().map(|s| s.name).collect();
                return type_error(format!(
                    "model {} has no option {}; its options are {} and its per-element inputs {}",
                    py(info.name),
                    py(key),
                    py_list(&options),
                    py_list(&inputs)
                ));
            };
            specs[k].check(value)?;
            values[k].1 = value.clone();
        }
        // The improved variant's corrections, where the caller has not set them.
        for spec in specs {
            if let OptionKind::Variant { improved } = spec.kind {
                let on = values.iter().any(|(n, v)| *n == spec.name && *v == Value::Text(VARIANTS[1].into()));
                for name in improved.iter().filter(|_| on) {
                    if !given.iter().any(|(k, _)| k == name) {
                        let k = values.iter().position(|(n, _)| n == name).expect("a correction of the same table");
                        values[k].1 = Value::Flag(true);
                    }
                }
            }
        }
        Ok(Args { values })
    }

    /// Every option of `specs` at its default.
    pub fn defaults(specs: &[OptionSpec]) -> Args {
        Args { values: specs.iter().map(|s| (s.name, s.default())).collect() }
    }

    /// The value of option `name`, if the model takes it.
    pub fn get(&self, name: &str) -> Option<&Value> {
        self.values.iter().find(|(n, _)| *n == name).map(|(_, v)| v)
    }

    fn value(&self, name: &str) -> Result<&Value> {
        self.get(name).ok_or_else(|| Error::Type(format!("no option {name:?} in this model's table")))
    }

    /// A flag's value.
    pub fn flag(&self, name: &str) -> Result<bool> {
        match self.value(name)? {
            Value::Flag(b) => Ok(*b),
            _ => type_error(format!("{name} must be a bool")),
        }
    }

    /// A number's value.
    pub fn number(&self, name: &str) -> Result<f64> {
        match self.value(name)? {
            Value::Number(x) => Ok(*x),
            _ => type_error(format!("{name} must be a number")),
        }
    }

    /// One number per channel, or one for all.
    pub fn channels(&self, name: &str) -> Result<Vec<f64>> {
        match self.value(name)? {
            Value::Number(x) => Ok(vec![*x]),
            Value::List(v) => Ok(v.clone()),
            _ => type_error(format!("{name} must be a number or one number per channel")),
        }
    }

    /// A choice, parsed into its type.
    pub fn choice<T: FromStr<Err = Error>>(&self, name: &str) -> Result<T> {
        match self.value(name)? {
            Value::Text(s) => s.parse(),
            _ => type_error(format!("{name} must be a string")),
        }
    }

    /// Whether a choice has the value `which`.
    pub fn is(&self, name: &str, which: &str) -> Result<bool> {
        match self.value(name)? {
            Value::Text(s) => Ok(s == which),
            _ => type_error(format!("{name} must be a string")),
        }
    }
}

/// The microsurface of every rough boundary from the options `distribution` and `g2` (the reference's and
/// `model="tabulated"`'s).
pub fn microsurface(args: &Args) -> Result<Microsurface> {
    Ok(Microsurface { distribution: args.choice("distribution")?, g2: args.choice("g2")? })
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

/// A number in [lo, hi].
pub const fn number(name: &'static str, lo: f64, hi: f64, default: f64, doc: &'static str) -> OptionSpec {
    OptionSpec { name, kind: OptionKind::Number { lo, hi, default }, doc }
}

/// `variant`: "published" or "improved", which switches on the corrections `improved` (flags of the same table).
pub const fn variant(improved: &'static [&'static str], doc: &'static str) -> OptionSpec {
    OptionSpec { name: "variant", kind: OptionKind::Variant { improved }, doc }
}

/// The microfacet distribution, with its default.
pub const fn distribution(default: &'static str) -> OptionSpec {
    choice("distribution", &Distribution::NAMES, default, "microfacet distribution")
}

/// The masking-shadowing form, with its default.
pub const fn g2(default: &'static str, doc: &'static str) -> OptionSpec {
    choice("g2", &G2Form::NAMES, default, doc)
}

pub const DISTRIBUTION: OptionSpec = distribution("ggx");
pub const G2: OptionSpec =
    g2("height_correlated", "masking-shadowing: Smith (height-correlated or separable, as Mitsuba 3) or V-cavity");
pub const FRESNEL: OptionSpec =
    choice("fresnel", &FresnelForm::NAMES, "exact", "Fresnel form: exact, Schlick, or Lazányi–Szirmay-Kalos");
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
     solution (its mean exact: the light the model misses added, its lobes' energy set); isotropic stacks",
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::CATALOGUE;

    #[test]
    fn every_option_takes_its_default_and_its_other_values_and_nothing_else() {
        for info in CATALOGUE {
            let defaults = Args::parse(info, &[]).unwrap();
            for spec in info.options {
                // Its default, given, is a valid value that changes nothing.
                let given = [(spec.name.to_string(), spec.default())];
                assert_eq!(Args::parse(info, &given).unwrap(), defaults, "{}", spec.name);
                // Every other value reaches the option.
                for v in spec.others() {
                    let given = [(spec.name.to_string(), v.clone())];
                    let args = Args::parse(info, &given).unwrap();
                    assert_eq!(args.get(spec.name), Some(&v), "{}.{}", info.name, spec.name);
                }
            }
            // An option of another model's table that this one lacks is a TypeError naming it.
            for other in CATALOGUE.iter().flat_map(|m| m.options) {
                if !info.options.iter().any(|s| s.name == other.name) {
                    let err = Args::parse(info, &[(other.name.into(), other.default())]);
                    assert!(
                        matches!(&err, Err(Error::Type(m)) if m.contains(&format!("has no option '{}'", other.name))),
                        "{}: {err:?}",
                        info.name
                    );
                }
            }
        }
    }

    #[test]
    fn values_outside_an_option_range_are_refused_by_kind() {
        const SPECS: &[OptionSpec] = &[DISTRIBUTION, number("x", 0.0, 1.0, 0.5, "a number"), ETA2];
        let properties =
            crate::models::Properties { reciprocal: true, energy_conserving: true, anisotropic: true, spectral: true };
        let info = ModelInfo { options: SPECS, properties, ..crate::models::REFERENCE };
        let parse = |k: &str, v: Value| Args::parse(&info, &[(k.into(), v)]);
        assert!(matches!(parse("distribution", Value::Text("phong".into())), Err(Error::Value(_))));
        assert!(matches!(parse("distribution", Value::Flag(true)), Err(Error::Type(_))));
        assert!(matches!(parse("x", Value::Number(1.5)), Err(Error::Value(_))));
        assert!(matches!(parse("x", Value::Text("a".into())), Err(Error::Type(_))));
        assert!(matches!(parse("eta2", Value::Number(1.0)), Err(Error::Type(_))));
    }

    #[test]
    fn the_improved_variant_sets_its_corrections_and_given_options_override_them() {
        for info in CATALOGUE {
            let Some(OptionKind::Variant { improved }) =
                info.options.iter().find(|s| s.name == "variant").map(|s| s.kind)
            else {
                continue;
            };
            assert!(!improved.is_empty(), "{}", info.name);
            let text = |s: &str| ("variant".to_string(), Value::Text(s.into()));
            let on = Args::parse(info, &[text("improved")]).unwrap();
            let published = Args::parse(info, &[text("published")]).unwrap();
            for name in improved.iter() {
                assert_eq!(on.flag(name), Ok(true), "{}: {name}", info.name);
                assert_eq!(published.flag(name), Ok(false), "{}: {name}", info.name);
                let off = [text("improved"), (name.to_string(), Value::Flag(false))];
                assert_eq!(Args::parse(info, &off).unwrap().flag(name), Ok(false));
            }
        }
    }
}
