//! The `baffle` command's arguments (clap), one module a command, each turned into the
//! typed settings baffle-plan's stages take (`From`); the defaults are baffle-plan's, and
//! so are the options' help texts: the doc comment of the settings field an option sets
//! (`settings_args!`).

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
///
/// The options' help is the doc comment of the settings' field they set
/// (`$settings::FIELD_DOCS`, see `help_from_settings`), so the fields here carry no doc
/// comment; one that does keeps it as its help (for a text that must differ on the
/// command line).
macro_rules! settings_args {
    (
        $(#[$meta:meta])*
        pub struct $name:ident into $settings:ident {
            $($(#[$($field_attr:tt)*])* pub $field:ident: $ty:ty),+ $(,)?
        }
        $(rest { $($rest:ident: $value:expr),+ $(,)? })?
    ) => {
        $(#[$meta])*
        #[command(mut_args(|arg| $crate::args::help_from_settings(arg, &[$((stringify!($field), $crate::args::is_flatten!($([$($field_attr)*])*))),+], $settings::FIELD_DOCS)))]
        pub struct $name {
            $($(#[$($field_attr)*])* pub $field: $ty),+
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

/// Whether a field's attributes (each in brackets) make it a flattened group
/// (`#[command(flatten)]`) rather than an option.
macro_rules! is_flatten {
    () => { false };
    ([command(flatten $($more:tt)*)] $($rest:tt)*) => { true };
    ([$($attr:tt)*] $($rest:tt)*) => { $crate::args::is_flatten!($($rest)*) };
}
pub(crate) use is_flatten;

/// Gives an option declared by a `settings_args!` struct (`fields`: its field names, and
/// whether each is a flattened group) the doc comment of the settings field of its name as
/// its help, as clap's derive makes help from a doc comment: `-h` shows the first
/// paragraph (its trailing period dropped), `--help` the whole comment when it has more
/// than one. Other arguments, and options with a help of their own, are left as they are.
pub fn help_from_settings(arg: clap::Arg, fields: &[(&str, bool)], docs: &[(&str, &[&str])]) -> clap::Arg {
    let id = arg.get_id().as_str();
    let own_option = fields.iter().any(|&(name, flatten)| name == id && !flatten);
    if !own_option || arg.get_help().is_some() {
        return arg;
    }
    match docs.iter().find(|(name, _)| *name == id).and_then(|(_, lines)| help_texts(lines)) {
        Some((short, Some(long))) => arg.help(short).long_help(long),
        Some((short, None)) => arg.help(short),
        None => arg,
    }
}

/// The short and (for a comment of several paragraphs) long help of a doc comment, as
/// clap_derive 4 makes them (utils/doc_comments.rs, without its markdown feature): one
/// leading space of each line dropped, blank lines at the ends too; a paragraph's lines
/// trimmed and joined by spaces, paragraphs by a blank line; the short help's trailing
/// period (not an ellipsis) dropped. None for a field without a doc comment.
fn help_texts(doc: &[&str]) -> Option<(String, Option<String>)> {
    let mut lines: Vec<&str> = doc
        .iter()
        .skip_while(|s| s.trim().is_empty())
        .flat_map(|s| s.split('\n'))
        .map(|s| s.strip_prefix(' ').unwrap_or(s))
        .collect();
    while lines.last().is_some_and(|s| s.trim().is_empty()) {
        lines.pop();
    }
    let paragraphs: Vec<String> = lines
        .split(|s| s.trim().is_empty())
        .filter(|p| !p.is_empty())
        .map(|p| p.iter().map(|s| s.trim()).collect::<Vec<_>>().join(" "))
        .collect();
    let mut short = paragraphs.first()?.clone();
    if short.ends_with('.') && !short.ends_with("..") {
        short.pop();
    }
    let long = (paragraphs.len() > 1).then(|| paragraphs.join("\n\n"));
    Some((short, long))
}

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
    fn help_is_made_from_a_doc_comment_as_clap_derive_makes_it() {
        assert_eq!(help_texts(&[" One line.", " continued."]), Some(("One line. continued".into(), None)));
        assert_eq!(help_texts(&[" Wait..."]), Some(("Wait...".into(), None)));
        assert_eq!(
            help_texts(&["", " First  ", " paragraph.", "", "", " Second.", ""]),
            Some(("First paragraph".into(), Some("First paragraph.\n\nSecond.".into())))
        );
        assert_eq!(help_texts(&[]), None);
    }

    /// Every option has a help: one whose settings field lost its doc comment (or whose
    /// name no longer matches a documented field) would be listed bare.
    #[test]
    fn every_option_has_its_settings_fields_help() {
        use clap::CommandFactory;
        let command = crate::Cli::command();
        let mut missing = Vec::new();
        for sub in command.get_subcommands() {
            for arg in sub.get_arguments() {
                let id = arg.get_id().as_str();
                // `baffle template`'s face labels (TemplateLabelArgs) have none, as before.
                let template_label = sub.get_name() == "template" && ["baffle_label", "vsd_label", "aortic_label"].contains(&id);
                if arg.get_help().is_none() && !template_label {
                    missing.push(format!("{} --{}", sub.get_name(), id));
                }
            }
        }
        assert!(missing.is_empty(), "options without help: {missing:?}");
        let simulate = command.find_subcommand("simulate").unwrap();
        let out = simulate.get_arguments().find(|a| a.get_id() == "out").unwrap();
        assert!(out.get_help().unwrap().to_string().starts_with("Output directory: summary.json"));
    }

    #[test]
    fn counts_below_one_are_refused() {
        assert_eq!(at_least_one("3"), Ok(3));
        assert!(at_least_one("0").unwrap_err().contains("at least 1"));
        assert!(at_least_one("-2").is_err() && at_least_one("two").is_err());
    }
}
