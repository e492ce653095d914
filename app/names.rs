//! The library's vocabulary: the one place an enum of settings gets its names. [`names!`] gives a plain enum
//! (`Axis`, `Backend`, `GridKind`, `Mode`, …) its `ALL`, `name`, `from_name` and `choices`, `Display`, and, behind
//! the `cli` feature, `clap::ValueEnum`, all read from one table of spellings; the CLI, Python, the page's URL and
//! the panel parse and print through them, so a name is spelled once.

/// Gives `$ty` its names: `names!(Axis { Longest => "longest", X => "x" })`, optionally with a help line per value
/// (`Surface => "surface": "every voxel a triangle touches"`) for `--help`.
macro_rules! names {
    ($ty:ident { $($variant:ident => $name:literal $(: $help:literal)?),+ $(,)? }) => {
        impl $ty {
            /// Every value, in the order help texts and menus list them.
            pub const ALL: [$ty; <[&str]>::len(&[$($name),+])] = [$($ty::$variant),+];

            /// The value's name on the command line, in Python, URLs, JSON and the panel.
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }

            /// The value [`Self::name`] spells `name`.
            pub fn from_name(name: &str) -> Option<$ty> {
                Self::ALL.into_iter().find(|v| v.name() == name)
            }

            /// The names as a message lists them: `a, b or c`.
            pub fn choices() -> String {
                $crate::names::choices(&Self::ALL.map(Self::name))
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        #[cfg(all(feature = "cli", not(target_arch = "wasm32")))]
        impl clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                &Self::ALL
            }

            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                let value = clap::builder::PossibleValue::new(self.name());
                match self {
                    $($ty::$variant => Some(value $(.help($help))?)),+
                }
            }
        }
    };
}
pub(crate) use names;

/// `["a", "b", "c"]` as `a, b or c`.
pub fn choices(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => one.to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}
