//! Serde for [`Method`] (feature `serde`): a name, or a table with the parameters
//! (`{ method = "admm", rho = 2.0 }`), the form of `mhe.method` in the scenario files.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{Method, MethodKind, Scaling, unknown};
use crate::error::QpError;

/// `{ method = "…", scaling = "…", <the family's keys> }`.
#[derive(Deserialize)]
struct MethodTable {
    method: String,
    #[serde(default)]
    scaling: Option<Scaling>,
    #[serde(flatten)]
    params: BTreeMap<String, f64>,
}

impl MethodTable {
    fn into_method(self) -> std::result::Result<Method, String> {
        let name = self.method.as_str();
        let Some((base, keys, with)) = MethodKind::preset(name) else {
            return Err(unknown(name).to_string());
        };
        if let Some(key) = self.params.keys().find(|k| !keys.contains(&k.as_str())) {
            let allowed = if keys.is_empty() {
                "it has none".to_string()
            } else {
                format!("its parameters: {}", keys.join(", "))
            };
            return Err(format!(
                "`{key}` is not a parameter of `{name}` ({allowed}; and `scaling`)"
            ));
        }
        let params = &self.params;
        let kind = with(base, &|k| params.get(k).copied());
        let m = Method {
            kind,
            scaling: self.scaling.unwrap_or_default(),
        };
        m.validate().map_err(|e| e.to_string())?;
        Ok(m)
    }
}

impl Serialize for Method {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        if Method::PRESETS.contains(self) || Method::JACOBI_PRESETS.contains(self) {
            return s.serialize_str(&self.name());
        }
        let keys = self.kind.keys();
        let scaled = self.scaling != Scaling::None;
        let mut map = s.serialize_map(Some(1 + keys.len() + usize::from(scaled)))?;
        map.serialize_entry("method", self.family())?;
        for (k, v) in &keys {
            map.serialize_entry(k, v)?;
        }
        if scaled {
            map.serialize_entry("scaling", &self.scaling)?;
        }
        map.end()
    }
}

impl<'de> Deserialize<'de> for Method {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Method;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(
                    f,
                    "a method name ({}, each optionally with \"-jacobi\") or a table \
                     {{ method = \"…\", <its parameters>, scaling = \"jacobi\" }}",
                    MethodKind::preset_names().join(", ")
                )
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Method, E> {
                v.parse().map_err(|e: QpError| E::custom(e))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> std::result::Result<Method, A::Error> {
                let table = MethodTable::deserialize(de::value::MapAccessDeserializer::new(map))?;
                table.into_method().map_err(de::Error::custom)
            }
        }
        d.deserialize_any(V)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn names_round_trip_through_serde() {
        for m in Method::PRESETS {
            let s = serde_json::to_string(&m).unwrap();
            assert_eq!(s, format!("\"{m}\""));
            assert_eq!(serde_json::from_str::<Method>(&s).unwrap(), m);
        }
        for m in [
            Method::pg(Some(0.05)).unwrap(),
            Method::admm(Some(2.0), 1.5).unwrap(),
            Method::admm(None, 1.2).unwrap(),
        ] {
            let s = serde_json::to_string(&m).unwrap();
            assert_eq!(serde_json::from_str::<Method>(&s).unwrap(), m, "{s}");
        }
    }

    #[test]
    fn bad_tables_name_the_parameter() {
        for (text, needle) in [
            (r#"{"method":"pg","rho":1.0}"#, "`rho`"),
            (r#"{"method":"admm","alpha":3.0}"#, "alpha"),
            (r#"{"method":"admm","rho":-1.0}"#, "rho"),
            (r#"{"method":"newton"}"#, "newton"),
            (r#""newton""#, "newton"),
            (r#"{"method":"pg","typo":1.0}"#, "typo"),
        ] {
            let e = serde_json::from_str::<Method>(text)
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }
}
