//! The defaults scenes/README.md documents are the ones a scene file gets: every `| field |
//! default | meaning |` row of the animation tables and of `quality: Reference`'s, and the inline `sun:`, `cloud:` and `shot`
//! defaults, parsed as a scene file parses them and compared with `Default`.

use nephele::animate::{AggregationConfig, DiffusionConfig};
use nephele::render::{CloudMaterial, Sun};
use serde::de::DeserializeOwned;

const README: &str = include_str!("../../scenes/README.md");

fn parse<T: DeserializeOwned>(text: &str) -> T {
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(text)
        .unwrap_or_else(|e| panic!("scenes/README.md: `{text}` does not parse: {e}"))
}

/// The `(field, default)` rows of the table that follows the line starting with `after`; a
/// default is kept only when its cell is one code span (`(required)` and prose are skipped).
fn table_rows(after: &str) -> Vec<(String, String)> {
    let start = README
        .find(after)
        .unwrap_or_else(|| panic!("scenes/README.md has no line starting {after:?}"));
    README[start..]
        .lines()
        .skip_while(|l| !l.starts_with("| field | default"))
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let field = cells.get(1)?.strip_prefix('`')?.strip_suffix('`')?;
            let default = cells.get(2)?.strip_prefix('`')?.strip_suffix('`')?;
            (!default.contains('`')).then(|| (field.to_string(), default.to_string()))
        })
        .collect()
}

/// Every documented default of a table, given alone, equals the type's `Default`.
fn check_table<T: DeserializeOwned + PartialEq + std::fmt::Debug>(
    after: &str,
    prefix: &str,
    want: &T,
    least_rows: usize,
) {
    let rows = table_rows(after);
    assert!(
        rows.len() >= least_rows,
        "{after}: only {} rows with a default found: {rows:?}",
        rows.len()
    );
    for (field, default) in rows {
        let got: T = parse(&format!("({prefix}{field}: {default})"));
        assert_eq!(
            &got, want,
            "scenes/README.md documents `{field}: {default}` as the default of {after:?}, \
             but the code's default differs"
        );
    }
}

/// The text of the code span that starts with `start` (e.g. "sun: (").
fn inline_default(start: &str) -> String {
    let at = README
        .find(&format!("`{start}"))
        .unwrap_or_else(|| panic!("scenes/README.md has no `{start}…`"));
    let rest = &README[at + 1..];
    rest[..rest.find('`').expect("an unclosed code span")].replace('\n', " ")
}

#[test]
fn the_animation_tables_match_the_defaults() {
    check_table("`Diffusion((...))`", "", &DiffusionConfig::default(), 6);
    check_table(
        "`Aggregation((...))`",
        "",
        &AggregationConfig::default(),
        11,
    );
    let morph: nephele::animate::morph::MorphConfig<()> = parse("(from: ())");
    check_table("`Morph((from: TARGET, ...))`", "from: (), ", &morph, 3);
    check_table(
        "Its settings, in the optional scene field `reference`",
        "",
        &nephele::render::PathTracing::default(),
        3,
    );
}

#[test]
fn the_inline_sun_cloud_and_shot_defaults_match() {
    let sun = inline_default("sun: (");
    let sun: Sun = parse(sun.strip_prefix("sun: ").unwrap());
    assert_eq!(sun, Sun::default(), "scenes/README.md's `sun:` default");
    let cloud = inline_default("cloud: (");
    let cloud: CloudMaterial = parse(cloud.strip_prefix("cloud: ").unwrap());
    assert_eq!(
        cloud,
        CloudMaterial::default(),
        "scenes/README.md's `cloud:` default"
    );
    let shot: Vec<(String, String)> = table_rows("### The rest")
        .into_iter()
        .filter(|(f, _)| f == "shot")
        .collect();
    assert_eq!(shot.len(), 1, "the rest table documents `shot`");
    let spec: nephele::scene::ShotSpec = parse(&shot[0].1);
    assert_eq!(
        spec,
        nephele::scene::ShotSpec::default(),
        "scenes/README.md's `shot` default"
    );
}
