//! Editing pipeline text key by key (`bench sweep` sets `accel.split`, `render.spp`,
//! `output[0].method`), keeping the rest of the file as written.

/// Sets `key` (dotted, with `[i]` for an array element: `output[0].method`) to `value`, parsed as
/// a TOML value, or taken as a string when it is not one (`sah`, `cook-torrance`).
pub(super) fn set_key(
    doc: &mut toml_edit::DocumentMut,
    key: &str,
    value: &str,
) -> Result<(), String> {
    use toml_edit::{Item, Table, TableLike, Value};
    let parsed = value
        .parse::<Value>()
        .unwrap_or_else(|_| Value::from(value));
    let segments: Vec<&str> = key.split('.').collect();
    let (last, path) = segments
        .split_last()
        .expect("split yields at least one part");
    if last.is_empty() || last.contains('[') {
        return Err(format!("key '{key}' must end in a key name"));
    }
    let mut table: &mut dyn TableLike = doc.as_table_mut();
    for segment in path {
        let (name, index) = match segment.split_once('[') {
            Some((n, rest)) => {
                let i = rest
                    .strip_suffix(']')
                    .and_then(|r| r.parse::<usize>().ok())
                    .ok_or_else(|| format!("key '{key}': bad index in '{segment}'"))?;
                (n, Some(i))
            }
            None => (*segment, None),
        };
        if name.is_empty() {
            return Err(format!("key '{key}' has an empty part"));
        }
        if index.is_none() && table.get(name).is_none() {
            table.insert(name, Item::Table(Table::new()));
        }
        let item = table
            .get_mut(name)
            .ok_or_else(|| format!("key '{key}': the pipeline has no '{name}'"))?;
        table = match (item, index) {
            (Item::ArrayOfTables(a), Some(i)) => {
                let len = a.len();
                a.get_mut(i)
                    .map(|t| t as &mut dyn TableLike)
                    .ok_or_else(|| format!("key '{key}': '{name}' has {len} entries, no [{i}]"))?
            }
            (Item::Value(Value::Array(a)), Some(i)) => {
                let len = a.len();
                a.get_mut(i)
                    .and_then(|v| v.as_inline_table_mut())
                    .map(|t| t as &mut dyn TableLike)
                    .ok_or_else(|| {
                        format!("key '{key}': '{name}' has {len} entries, no table at [{i}]")
                    })?
            }
            (item, None) => item
                .as_table_like_mut()
                .ok_or_else(|| format!("key '{key}': '{name}' is not a table"))?,
            (_, Some(_)) => return Err(format!("key '{key}': '{name}' is not an array")),
        };
    }
    table.insert(last, Item::Value(parsed));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::SplitMethod;
    use crate::pipeline::Pipeline;
    use std::path::Path;

    #[test]
    fn keys_are_set_by_path_in_tables_and_arrays_of_tables() {
        let src = "[scene]\npath = \"s.gltf\"\n[render]\nspp = 4\n[[output]]\nkind = \"anaglyph\"\npath = \"a.png\"\n";
        let mut doc = src.parse::<toml_edit::DocumentMut>().unwrap();
        set_key(&mut doc, "render.spp", "16").unwrap();
        set_key(&mut doc, "accel.split", "center").unwrap(); // a table the file lacks
        set_key(&mut doc, "output[0].method", "gray").unwrap();
        set_key(&mut doc, "stereo.interaxial", "0.1").unwrap();
        let p = Pipeline::parse(Path::new("p.toml"), &doc.to_string()).unwrap();
        assert_eq!(p.render.spp, 16);
        assert_eq!(p.accel.split, SplitMethod::Center);
        assert_eq!(p.stereo.interaxial, crate::pipeline::Metres::Fixed(0.1));
        assert!(doc.to_string().contains("method = \"gray\""));
        for (key, why) in [
            ("output[3].method", "has 1 entries"),
            ("render[0].spp", "not an array"),
            ("render.", "must end in a key name"),
            ("output[x].path", "bad index"),
        ] {
            let err = set_key(&mut doc, key, "1").unwrap_err();
            assert!(err.contains(why), "{key}: {err}");
        }
    }
}
