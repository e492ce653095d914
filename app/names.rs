//! The library's vocabulary: the one place an enum of settings gets its names. `names!` gives a plain enum
//! (`Axis`, `Backend`, `GridKind`, `Mode`, …) its `ALL`, `name`, `from_name` and `choices`, `Display`, and, behind
//! the `cli` feature, `clap::ValueEnum`, all read from one table of spellings; the CLI, Python, the page's URL and
//! the panel parse and print through them, so a name is spelled once. Messages name the settings a user gives
//! through [`Setting`], which each client spells its own way with [`spell_settings_with`].

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

/// A setting a user gives, as messages name it: a flag on the command line (`--band`), a keyword in Python
/// (`band=`), a control of the panel. The library's messages name settings only through this type, and each client
/// spells them its own way, in one place, with [`spell_settings_with`]; without a client the library's own words
/// are used (the setting's [`Setting::word`], and `word=value`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setting {
    Attributes,
    Axis,
    Backend,
    Band,
    Block,
    Drain,
    FillPockets,
    Grid,
    Level,
    MaxFileSize,
    MaxMemory,
    MaxTriangles,
    Merge,
    Mode,
    Output,
    Resolution,
    ResourceRoot,
    Size,
    Thickness,
    Unit,
    VoxelSize,
}

impl Setting {
    /// The library's word for the setting (Python's keyword too, but for the voxel size, which Python calls `pitch`).
    pub fn word(self) -> &'static str {
        match self {
            Setting::Attributes => "attributes",
            Setting::Axis => "axis",
            Setting::Backend => "backend",
            Setting::Band => "band",
            Setting::Block => "block",
            Setting::Drain => "drain",
            Setting::FillPockets => "fill_pockets",
            Setting::Grid => "grid",
            Setting::Level => "level",
            Setting::MaxFileSize => "max_file_size",
            Setting::MaxMemory => "max_memory",
            Setting::MaxTriangles => "max_triangles",
            Setting::Merge => "merge",
            Setting::Mode => "mode",
            Setting::Output => "output",
            Setting::Resolution => "resolution",
            Setting::ResourceRoot => "resource_root",
            Setting::Size => "size",
            Setting::Thickness => "thickness",
            Setting::Unit => "unit",
            Setting::VoxelSize => "voxel_size",
        }
    }

    /// The setting given `value`, as the client spells it (`--band full`, `band="full"`).
    pub fn with(self, value: impl std::fmt::Display) -> Spelled {
        Spelled { setting: self, value: value.to_string() }
    }
}

/// How a client spells a setting, with a value or without.
pub type Speller = fn(Setting, Option<&str>) -> String;

static SPELLER: std::sync::RwLock<Option<Speller>> = std::sync::RwLock::new(None);

/// Makes every message spell settings as `speller` does, from now on, in this process: the CLI, the Python module
/// and the viewer call it once as they start.
pub fn spell_settings_with(speller: Speller) {
    *SPELLER.write().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(speller);
}

fn spell(setting: Setting, value: Option<&str>) -> String {
    match *SPELLER.read().unwrap_or_else(std::sync::PoisonError::into_inner) {
        Some(speller) => speller(setting, value),
        None => match value {
            None => setting.word().to_string(),
            Some(value) => format!("{}={value}", setting.word()),
        },
    }
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&spell(*self, None))
    }
}

/// A setting with its value, in a message ([`Setting::with`]).
#[derive(Clone, Debug)]
pub struct Spelled {
    setting: Setting,
    value: String,
}

impl std::fmt::Display for Spelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&spell(self.setting, Some(&self.value)))
    }
}
