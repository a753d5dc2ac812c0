//! [`code_table!`]: a total wire code table.

/// Defines a total wire code table: named variants, an `Unknown(raw)` fallback, conversions
/// both ways, a description (from the specification's table), `Display` (the description;
/// an unknown code shows its raw value) and serde as the raw number. The crate that uses it
/// depends on `serde` (with `derive`).
///
/// ```
/// motus_wire::code_table! {
///     /// NMT commands.
///     Command: u8 as "u8" {
///         /// Start.
///         Start = 0x01 => "start remote node",
///     }
/// }
/// assert_eq!(Command::from_raw(1), Command::Start);
/// assert_eq!(Command::from_raw(7), Command::Unknown(7));
/// assert_eq!(Command::Start.to_string(), "start remote node");
/// assert_eq!(Command::Unknown(7).to_string(), "unknown (0x07)");
/// ```
#[macro_export]
macro_rules! code_table {
    ($(#[$m:meta])* $name:ident : $ty:ty as $tys:literal { $($(#[$vm:meta])* $var:ident = $val:expr => $desc:expr,)* }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
        #[serde(from = $tys, into = $tys)]
        pub enum $name {
            $($(#[$vm])* $var,)*
            /// A value this table does not name, kept raw.
            Unknown($ty),
        }
        impl $name {
            /// Classifies a raw wire value.
            pub fn from_raw(raw: $ty) -> Self {
                match raw { $(v if v == $val => Self::$var,)* other => Self::Unknown(other) }
            }
            /// The raw wire value.
            pub fn raw(self) -> $ty {
                match self { $(Self::$var => $val,)* Self::Unknown(raw) => raw }
            }
            /// Human-readable meaning (from the specification's table).
            pub fn description(self) -> &'static str {
                match self { $(Self::$var => $desc,)* Self::Unknown(_) => "unknown" }
            }
        }
        impl From<$ty> for $name {
            fn from(raw: $ty) -> Self { Self::from_raw(raw) }
        }
        impl From<$name> for $ty {
            fn from(code: $name) -> Self { code.raw() }
        }
        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                match self {
                    Self::Unknown(raw) => write!(f, "unknown ({raw:#04x})"),
                    other => f.write_str(other.description()),
                }
            }
        }
    };
}
