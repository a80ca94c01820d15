//! `cargo xtask sweep-merge`: the shards' metadata checked as one set, then the point files merged.

use super::*;

/// (I, N) of a shard meta's file name `meta.shard-I-of-N.json` (1 ≤ I ≤ N), else None.
pub(super) fn shard_of_meta_name(name: &str) -> Option<(usize, usize)> {
    let (i, n) = name
        .strip_prefix("meta.shard-")?
        .strip_suffix(".json")?
        .split_once("-of-")?;
    let (i, n) = (i.parse::<usize>().ok()?, n.parse::<usize>().ok()?);
    (1 <= i && i <= n).then_some((i, n))
}

/// Checks that the shard metas found (`paths`) are exactly one sharding's: every name
/// `meta.shard-I-of-N.json` with one N, each I of 1..=N once. None found is fine (a merge
/// of unsharded directories, or of an `--out` alone).
pub(super) fn check_shard_set(paths: &[PathBuf]) -> Result<()> {
    let fix = "sweep-merge takes the directories of one sharded run: every shard I of N \
               once, with its meta.shard-I-of-N.json";
    let mut found: Vec<(usize, usize, &Path)> = Vec::new();
    for p in paths {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let Some((i, n)) = shard_of_meta_name(name) else {
            bail!(
                "`{}` is not a shard meta's name (meta.shard-I-of-N.json, 1 ≤ I ≤ N): a \
                 stray file; remove it. {fix}",
                p.display()
            );
        };
        if let Some((_, _, other)) = found.iter().find(|(fi, fnn, _)| (*fi, *fnn) == (i, n)) {
            bail!(
                "shard {i} of {n} is there twice (`{}` and `{}`); keep one. {fix}",
                other.display(),
                p.display()
            );
        }
        found.push((i, n, p));
    }
    let Some(&(_, n, first)) = found.first() else {
        return Ok(());
    };
    if let Some((i, m, p)) = found.iter().find(|(_, m, _)| *m != n) {
        bail!(
            "`{}` is shard {i} of {m}, but `{}` is of a {n}-shard run: a stray of another \
             sharding; remove it. {fix}",
            p.display(),
            first.display()
        );
    }
    if let Some(i) = (1..=n).find(|i| !found.iter().any(|(fi, _, _)| fi == i)) {
        bail!(
            "meta.shard-{i}-of-{n}.json is missing from every input directory (found {} of \
             the {n} shards' metas); restore it from the shard's run, or rerun shard {i}/{n}. \
             {fix}",
            found.len()
        );
    }
    Ok(())
}

/// The shards' own meta files in `dirs` (`meta.shard-*.json`), read and parsed before
/// anything is merged: an unreadable or malformed one is an error naming it, not a gap in
/// `meta.json`; they must be exactly one sharding's ([`check_shard_set`]), and each one's
/// `shard` field must be its name's.
pub(super) fn shard_metas(dirs: &[&Path]) -> Result<Vec<serde_json::Value>> {
    let mut all = Vec::new();
    for d in dirs {
        let Ok(rd) = std::fs::read_dir(d) else {
            continue;
        };
        let mut names: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with("meta.shard-") && n.ends_with(".json"))
            })
            .collect();
        names.sort();
        all.extend(names);
    }
    check_shard_set(&all)?;
    let mut shards = Vec::new();
    for p in all {
        let fix = "restore it from the shard's run, or rerun that shard; sweep-merge keeps \
                       every shard's meta in meta.json";
        let text = crate::output::read_input(&p).map_err(|e| {
            anyhow::anyhow!("cannot read the shard meta `{}`: {e}; {fix}", p.display())
        })?;
        let v = serde_json::from_str::<serde_json::Value>(&text).map_err(|e| {
            anyhow::anyhow!(
                "the shard meta `{}` is not valid JSON ({e}); {fix}",
                p.display()
            )
        })?;
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if let Some((i, n)) = shard_of_meta_name(name) {
            let want = format!("{i}/{n}");
            let recorded = v.pointer("/run/shard");
            if recorded.and_then(|s| s.as_str()) != Some(want.as_str()) {
                bail!(
                    "the shard meta `{}` does not record shard {want} (its `shard` is {}): \
                         renamed or edited; {fix}",
                    p.display(),
                    recorded.map_or("missing".to_string(), |s| s.to_string())
                );
            }
        }
        shards.push(json!({"file": p.display().to_string(), "meta": v}));
    }
    Ok(shards)
}

/// `cargo xtask sweep-merge`.
pub fn merge(args: &MergeArgs) -> Result<()> {
    let start = unix_now();
    check_out_dir(&args.out, "--out")?;
    let (config_text, sweep) = load(&args.config)?;
    let inputs: Vec<&Path> = if args.inputs.is_empty() {
        vec![args.out.as_path()]
    } else {
        args.inputs.iter().map(PathBuf::as_path).collect()
    };
    // The shards' meta files are read before anything is written (kept for the record).
    let shards = shard_metas(&inputs)?;
    // runs.csv and points.csv are committed in one set with the plots and meta.json.
    let (n, staged) = merge_staged(&sweep, &inputs, &args.out, &Notices)?;
    let mut plots = Vec::new();
    write_set(&args.out, staged.outputs.as_ref(), |set, table| {
        let table = table.ok_or_else(|| anyhow!("the merge assembled no points.csv"))?;
        let (thresholds, pairs) = sweep.all_thresholds(table);
        plots = draw(&sweep, set, table, &pairs)?;
        let extra = json!({
            "merged_from": inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "shard_meta": shards,
            "plots": plots,
            "thresholds": super::records::thresholds(&thresholds),
            "files": set.manifest(),
        });
        let extra = with_2d(&sweep, extra, &pairs);
        let text = json_text(&meta(
            &sweep,
            &args.config,
            &config_text,
            (start, unix_now()),
            extra,
        ))?;
        set.add("meta.json", text.as_bytes())?;
        Ok(())
    })?;
    outln!(
        "merged {n} points from {} directories into {}/{{runs.csv, points.csv, {}meta.json}} and {} plots",
        inputs.len(),
        args.out.display(),
        if sweep.config().kalman {
            "kalman.csv, "
        } else {
            ""
        },
        plots.len()
    );
    Ok(())
}
