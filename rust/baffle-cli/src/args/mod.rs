//! The `baffle` command's arguments (clap), one module a command, each turned into the
//! typed settings baffle-plan's stages take (`From`); the defaults are baffle-plan's.

/// A clap value enum with the variants of the baffle-plan enum `$plan` (imported under
/// that name), converted both ways.
macro_rules! value_enum {
    ($(#[$doc:meta])* $name:ident mirrors $plan:ident { $($variant:ident),+ $(,)? }) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
        pub enum $name {
            $($variant),+
        }

        impl From<$name> for $plan {
            fn from(v: $name) -> Self {
                match v {
                    $($name::$variant => $plan::$variant),+
                }
            }
        }

        impl From<$plan> for $name {
            fn from(v: $plan) -> Self {
                match v {
                    $($plan::$variant => $name::$variant),+
                }
            }
        }
    };
}
pub(crate) use value_enum;

/// A clap `Args` struct whose every field sets the same-named field of the baffle-plan
/// settings `$settings` (through `Into`: a flattened group, a value enum), and that
/// `From` conversion; the settings' fields the command line does not set follow the
/// struct (`rest { field: value }`). One list of fields, so that an option cannot be
/// parsed and then left out of the settings.
macro_rules! settings_args {
    (
        $(#[$meta:meta])*
        pub struct $name:ident into $settings:ident {
            $($(#[$field_meta:meta])* pub $field:ident: $ty:ty),+ $(,)?
        }
        $(rest { $($rest:ident: $value:expr),+ $(,)? })?
    ) => {
        $(#[$meta])*
        pub struct $name {
            $($(#[$field_meta])* pub $field: $ty),+
        }

        impl From<$name> for $settings {
            fn from(a: $name) -> Self {
                $settings {
                    $($field: a.$field.into(),)+
                    $($($rest: $value,)+)?
                }
            }
        }
    };
}
pub(crate) use settings_args;

pub mod centerline;
pub mod design;
pub mod export;
pub mod extend;
pub mod mesh;
pub mod plan;
pub mod prepare;
pub mod simulate;
pub mod sweep;
pub mod template;

/// A count option that must be at least 1 (--cycles, --mpi-processes).
pub fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        Ok(_) => Err("must be at least 1".into()),
        Err(e) => Err(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_below_one_are_refused() {
        assert_eq!(at_least_one("3"), Ok(3));
        assert!(at_least_one("0").unwrap_err().contains("at least 1"));
        assert!(at_least_one("-2").is_err() && at_least_one("two").is_err());
    }
}
