//! The library names an option by its name in the library (`the `max_order` option`), and a
//! setting as `` `time_unit = ms` ``, as a Rust or Python caller passes it; the command line says
//! its flag (`--max-order`, `` `--time-unit ms` ``). Every error, report warning and summary the
//! CLI prints or writes goes through [`in_cli_words`].

/// The library's option names and the flags that set them.
const FLAGS: &[(&str, &str)] = &[
    ("max_order", "--max-order"),
    ("motion_degree", "--motion-degree"),
    ("heads", "--heads"),
    ("pole_pairs", "--pole-pairs"),
    ("bridge_gap", "--bridge-gap"),
    ("latency", "--latency"),
    ("ref_reversed", "--ref-reversed"),
    ("target_tol", "--target-tol"),
    ("ref_u", "--ref-u"),
    ("ref_table", "--ref-table"),
    ("budget", "--budget"),
    ("ref", "--ref"),
    ("time_unit", "--time-unit"),
    ("time_column", "--time-column"),
    ("ref_ratio", "--ref-ratio"),
    ("ref_orders", "--ref-orders"),
    ("time", "--time"),
    ("skip_damaged", "--skip-damaged"),
    ("keep", "--keep"),
    ("scale_arcsec", "--scale"),
    ("points", "--points"),
    ("moteus_source", "--source"),
    ("format", "--format"),
    ("unit", "--unit"),
    ("faces", "--faces"),
    ("max_gap", "--max-gap"),
    ("min_amplitude", "--min-amplitude"),
    ("max_copy_bytes", "--max-copy (in MB)"),
];

/// `text` with each option the library names (`the `max_order` option`, `a lower `max_order`
/// option`) said as its flag (`--max-order`, `a lower --max-order`), and each setting
/// (`` `time_unit = ms` ``) as the flag and its value (`` `--time-unit ms` ``).
pub fn in_cli_words(text: &str) -> String {
    if !text.contains("` option") && !text.contains(" = ") {
        return text.to_string();
    }
    FLAGS.iter().fold(text.to_string(), |t, (name, flag)| {
        t.replace(&format!("the `{name}` option"), flag)
            .replace(
                &format!("a lower `{name}` option"),
                &format!("a lower {flag}"),
            )
            .replace(&format!("`{name} = "), &format!("`{flag} "))
            .replace(&format!("`{name}` option"), flag)
    })
}

#[cfg(test)]
mod tests {
    use super::in_cli_words;

    #[test]
    fn library_options_become_flags() {
        assert_eq!(
            in_cli_words("lower the `max_order` option or the `motion_degree` option"),
            "lower --max-order or --motion-degree"
        );
        assert_eq!(
            in_cli_words("(try a lower `max_order` option)"),
            "(try a lower --max-order)"
        );
        // A channel that happens to share an option's name is left alone.
        assert_eq!(in_cli_words("channel `latency`"), "channel `latency`");
        assert_eq!(
            in_cli_words("say `time_unit = ms`, or read them with `time = log`"),
            "say `--time-unit ms`, or read them with `--time log`"
        );
        assert_eq!(
            in_cli_words("run with the `skip_damaged` option (the `time_column` option)"),
            "run with --skip-damaged (--time-column)"
        );
        assert_eq!(
            in_cli_words("takes no `scale_arcsec` option; use `scale_arcsec = 1e-2`"),
            "takes no --scale; use `--scale 1e-2`"
        );
    }
}
