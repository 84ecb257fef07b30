//! Things a user names by a fixed id — an experiment, a robot, a link
//! profile — on the command line, in files and on the wire: one list of
//! ids per kind, one parser, one way to say what the valid ids are.

/// A closed set of values, each with an id.
pub trait Named: Sized + Copy + PartialEq + 'static {
    /// What one of these is called, for messages: "experiment".
    const KIND: &'static str;
    /// Every value, in the order they are listed to users.
    const ALL: &'static [Self];

    /// Ids once used for some values: refused, with the id to use now.
    const FORMERLY: &'static [(&'static str, Self)] = &[];

    fn id(self) -> &'static str;

    /// The value with this id.
    fn from_id(id: &str) -> Result<Self, UnknownName> {
        Self::ALL
            .iter()
            .copied()
            .find(|v| v.id() == id)
            .ok_or_else(|| UnknownName {
                kind: Self::KIND,
                name: id.to_owned(),
                known: Self::ALL.iter().map(|v| v.id()).collect(),
                now: Self::FORMERLY
                    .iter()
                    .find(|(old, _)| *old == id)
                    .map(|(_, v)| v.id()),
            })
    }
}

/// An id that names nothing, with the ids that do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {kind} '{name}'{renamed} (known: {known})",
    renamed = now.map(|n| format!(": it is called '{n}' now")).unwrap_or_default(),
    known = known.join(", "))]
pub struct UnknownName {
    pub kind: &'static str,
    pub name: String,
    pub known: Vec<&'static str>,
    /// The id of what `name` once named.
    pub now: Option<&'static str>,
}

/// `Display`, `FromStr` and serde as the id, for a [`Named`] type.
#[macro_export]
#[doc(hidden)]
macro_rules! named_by_id {
    ($t:ty) => {
        impl ::std::fmt::Display for $t {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str($crate::Named::id(*self))
            }
        }

        impl ::std::str::FromStr for $t {
            type Err = $crate::UnknownName;

            fn from_str(id: &str) -> Result<Self, Self::Err> {
                <$t as $crate::Named>::from_id(id)
            }
        }

        impl ::serde::Serialize for $t {
            fn serialize<S: ::serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str($crate::Named::id(*self))
            }
        }

        impl $crate::schemars::JsonSchema for $t {
            fn schema_name() -> ::std::borrow::Cow<'static, str> {
                <$t as $crate::Named>::KIND.into()
            }

            fn json_schema(_: &mut $crate::schemars::SchemaGenerator) -> $crate::schemars::Schema {
                let ids: Vec<&str> = <$t as $crate::Named>::ALL
                    .iter()
                    .map(|v| $crate::Named::id(*v))
                    .collect();
                $crate::schemars::json_schema!({"type": "string", "enum": ids})
            }
        }

        impl<'de> ::serde::Deserialize<'de> for $t {
            fn deserialize<D: ::serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let id = <::std::borrow::Cow<'de, str> as ::serde::Deserialize>::deserialize(d)?;
                <$t as $crate::Named>::from_id(&id).map_err(::serde::de::Error::custom)
            }
        }
    };
}
