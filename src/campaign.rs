//! Campaign identity: what makes the shard files of one campaign one campaign again
//! (README "Campaigns on a cluster").
//!
//! A sweep's *definition* is everything that decides its variants' numbers: the model
//! file's text, the `--set` values, the table of varied parameter values (every variant of
//! the whole campaign, not only a shard's), the output time grid, the sensors, the solver
//! overrides (`--accuracy`), the derived quantities asked for (`--frequency`), the element
//! backend and precision, and the latdyn version. It is written as a JSON object (keys
//! sorted, floats in Rust's round-trip `{:?}` form) and hashed with SHA-256; the
//! hash is stored in every sweep and shard file (`campaign_hash`), together with a
//! readable identifier (`campaign_id` = model file stem + the hash's first 12 hex
//! digits). What does not change a number is left out: the thread count, the shard, the
//! model file's path, the output path and the command line, so array tasks on different
//! nodes, with different thread counts or mount points, agree on the campaign without
//! talking to each other.

use std::path::Path;

use sha2::{Digest, Sha256};

use crate::output::SensorMeta;

/// A campaign's identity and the variant table it was defined with (stored under
/// `/campaign` and in the root attributes `campaign_id`, `campaign_hash`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CampaignInfo {
    /// model file stem + the first 12 hex digits of `hash`
    pub id: String,
    /// SHA-256 (hex) of `definition`
    pub hash: String,
    /// the definition, a JSON object (see the module docs)
    pub definition: String,
    /// names of the varied parameters (the `--variants` columns, then the `--vary` names)
    pub varied: Vec<String>,
    /// per variant of the whole campaign (global index order), its varied values
    pub variants: Vec<Vec<f64>>,
    /// the `--set` overrides shared by every variant
    pub set: Vec<(String, f64)>,
}

/// What a campaign is defined by (see the module docs).
pub struct DefinitionInput<'a> {
    pub model_path: &'a Path,
    pub model_source: &'a str,
    pub set: &'a [(String, f64)],
    pub variants: &'a [Vec<(String, f64)>],
    pub time: &'a [f64],
    pub sensors: &'a [SensorMeta],
    pub accuracy: Option<f64>,
    /// `--frequency`: sensor name and component index
    pub frequency: Option<&'a (String, usize)>,
    pub backend: &'a str,
    pub precision: &'a str,
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// `{:?}` of an f64 is the shortest text that parses back to the same bits (and spells
/// NaN and infinities, which JSON numbers cannot).
fn num(x: f64) -> String {
    format!("{x:?}")
}

/// The campaign's definition, its hash and identifier. Fails if the variant rows do not
/// all name the same parameters in the same order (a caller bug: `ensemble::variants`
/// builds them so).
pub fn identify(d: &DefinitionInput) -> Result<CampaignInfo, String> {
    let varied: Vec<String> = d
        .variants
        .first()
        .map(|r| r.iter().map(|(n, _)| n.clone()).collect())
        .unwrap_or_default();
    let mut table = Sha256::new();
    let mut variants = Vec::with_capacity(d.variants.len());
    for (i, row) in d.variants.iter().enumerate() {
        if row.len() != varied.len() || row.iter().zip(&varied).any(|((n, _), v)| n != v) {
            return Err(format!(
                "variant {i} names other parameters than variant 0 ({})",
                varied.join(", ")
            ));
        }
        for (_, x) in row {
            table.update(x.to_le_bytes());
        }
        variants.push(row.iter().map(|(_, x)| *x).collect::<Vec<f64>>());
    }
    let mut time = Sha256::new();
    for t in d.time {
        time.update(t.to_le_bytes());
    }
    let mut set = d.set.to_vec();
    // the order of --set options does not change the campaign; a repeated name keeps its
    // order (the last one given wins when the model is compiled)
    set.sort_by(|a, b| a.0.cmp(&b.0));
    let def = serde_json::json!({
        "latdyn_version": env!("CARGO_PKG_VERSION"),
        "model_sha256": hex(&Sha256::digest(d.model_source.as_bytes())),
        "set": set.iter().map(|(n, x)| serde_json::json!([n, num(*x)])).collect::<Vec<_>>(),
        "varied": varied,
        "variants": d.variants.len(),
        "variants_sha256": hex(&table.finalize()),
        "time": {
            "n": d.time.len(),
            "first": d.time.first().map(|t| num(*t)),
            "last": d.time.last().map(|t| num(*t)),
            "sha256": hex(&time.finalize()),
        },
        "sensors": d.sensors.iter().map(|s| format!(
            "{}({})[{}]", s.name, s.components.join(","), s.units.join(",")
        )).collect::<Vec<_>>(),
        "accuracy": d.accuracy.map(num),
        "frequency": d.frequency.map(|(n, c)| format!("{n}.{c}")),
        "backend": d.backend,
        "precision": d.precision,
    });
    // serde_json's map is a BTreeMap (no `preserve_order` feature): keys come out sorted,
    // so the text, and with it the hash, depends on the content only
    let definition = def.to_string();
    let hash = hex(&Sha256::digest(definition.as_bytes()));
    let stem = d
        .model_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "campaign".into());
    Ok(CampaignInfo {
        id: format!("{stem}-{}", &hash[..12]),
        hash,
        definition,
        varied,
        variants,
        set,
    })
}

/// What differs between two definitions (their JSON texts), one entry per top-level key,
/// e.g. `model_sha256` or `variants_sha256`; empty when they are equal or unreadable.
pub fn differences(a: &str, b: &str) -> Vec<String> {
    let (Ok(a), Ok(b)) = (
        serde_json::from_str::<serde_json::Value>(a),
        serde_json::from_str::<serde_json::Value>(b),
    ) else {
        return Vec::new();
    };
    let (Some(a), Some(b)) = (a.as_object(), b.as_object()) else {
        return Vec::new();
    };
    let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| {
            let show = |v: Option<&serde_json::Value>| {
                v.map(|v| {
                    let s = v.to_string();
                    if s.chars().count() > 80 {
                        format!("{}…", s.chars().take(80).collect::<String>())
                    } else {
                        s
                    }
                })
                .unwrap_or_else(|| "absent".into())
            };
            format!("{k}: {} vs {}", show(a.get(k)), show(b.get(k)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input<'a>(
        src: &'a str,
        set: &'a [(String, f64)],
        variants: &'a [Vec<(String, f64)>],
        time: &'a [f64],
    ) -> DefinitionInput<'a> {
        DefinitionInput {
            model_path: Path::new("models/m.toml"),
            model_source: src,
            set,
            variants,
            time,
            sensors: &[],
            accuracy: None,
            frequency: None,
            backend: "cpu",
            precision: "f64",
        }
    }

    #[test]
    fn hash_changes_with_every_part_of_the_definition_and_not_with_set_order() {
        let v = |x: f64| vec![vec![("omega".to_string(), 1.0)], vec![("omega".into(), x)]];
        let set = vec![("a".to_string(), 1.0), ("b".to_string(), 2.0)];
        let set_rev: Vec<_> = set.iter().rev().cloned().collect();
        let (v2, v3) = (v(2.0), v(3.0));
        let t = [0.0, 0.5, 1.0];
        let base = identify(&input("x = 1", &set, &v2, &t)).unwrap();
        assert_eq!(base.hash.len(), 64);
        assert!(base.id.starts_with("m-") && base.id.len() == 2 + 12);
        assert_eq!(base, identify(&input("x = 1", &set_rev, &v2, &t)).unwrap());
        let others = [
            identify(&input("x = 2", &set, &v2, &t)).unwrap(),
            identify(&input("x = 1", &set[..1], &v2, &t)).unwrap(),
            identify(&input("x = 1", &set, &v3, &t)).unwrap(),
            identify(&input("x = 1", &set, &v2, &t[..2])).unwrap(),
        ];
        for (o, what) in others.iter().zip(["model", "set", "variants", "time"]) {
            assert_ne!(o.hash, base.hash, "{what}");
            assert!(!differences(&base.definition, &o.definition).is_empty());
        }
        let d = differences(&base.definition, &others[2].definition);
        assert_eq!(d.len(), 1, "{d:?}");
        assert!(d[0].starts_with("variants_sha256"), "{d:?}");
    }
}
