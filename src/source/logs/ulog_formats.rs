//! A check of a ULog's format definitions before the `yule_log` parser sees them, for what
//! `catch_unwind` cannot contain: a nested type that contains itself (directly or through
//! others, or nested without end) makes the parser recurse until the stack overflows, and an array of a type of
//! no size, or longer than a record can hold, makes it allocate without bound. Both abort
//! the process. The parser reads formats only before the first subscription ('A'), so
//! that is where this looks.

use std::collections::HashMap;

/// Why the log's formats are unsafe to parse, or `None`.
pub(super) fn unsafe_formats(bytes: &[u8]) -> Option<String> {
    let mut formats: HashMap<String, Vec<(String, u64)>> = HashMap::new();
    let mut at = 16;
    while let Some(&[a, b, kind]) = bytes.get(at..at + 3) {
        let end = at + 3 + usize::from(u16::from_le_bytes([a, b]));
        let Some(body) = bytes.get(at + 3..end) else {
            break;
        };
        match kind {
            b'A' => break,
            b'F' => {
                let text = String::from_utf8_lossy(body);
                let Some((name, fields)) = text.split_once(':') else {
                    at = end;
                    continue;
                };
                let mut list = Vec::new();
                for f in fields.split(';') {
                    let ty = f.split_whitespace().next().unwrap_or("");
                    let (base, n) = match ty.split_once('[') {
                        Some((b, rest)) => {
                            let n = rest.trim_end_matches(']');
                            if !n.bytes().all(|c| c.is_ascii_digit()) {
                                (b, 1)
                            } else {
                                match n.parse::<u64>() {
                                    Ok(n) if n <= u64::from(u16::MAX) => (b, n),
                                    _ => {
                                        return Some(format!(
                                        "format {name}: an array of {n} (more than a record holds)"
                                    ))
                                    }
                                }
                            }
                        }
                        None => (ty, 1),
                    };
                    if !base.is_empty() {
                        list.push((base.to_string(), n));
                    }
                }
                formats.insert(name.to_string(), list);
            }
            _ => {}
        }
        at = end;
    }
    // Each format's size in bytes, with a cycle check (None while being sized).
    let mut size: HashMap<&str, Option<u64>> = HashMap::new();
    fn sized<'a>(
        name: &'a str,
        depth: usize,
        formats: &'a HashMap<String, Vec<(String, u64)>>,
        size: &mut HashMap<&'a str, Option<u64>>,
    ) -> Result<u64, String> {
        let primitive = match name {
            "int8_t" | "uint8_t" | "bool" | "char" => Some(1),
            "int16_t" | "uint16_t" => Some(2),
            "int32_t" | "uint32_t" | "float" => Some(4),
            "int64_t" | "uint64_t" | "double" => Some(8),
            _ => None,
        };
        if let Some(p) = primitive {
            return Ok(p);
        }
        let Some(fields) = formats.get(name) else {
            return Ok(1); // unknown: the parser says so itself
        };
        match size.get(name) {
            Some(Some(s)) => return Ok(*s),
            Some(None) => return Err(format!("format {name} contains itself")),
            None => {}
        }
        if depth > 32 {
            return Err(format!("format {name}: nested more than 32 deep"));
        }
        size.insert(name, None);
        let mut total = 0u64;
        for (ty, n) in fields {
            let s = sized(ty, depth + 1, formats, size)?;
            if s == 0 && *n != 1 {
                return Err(format!(
                    "format {name}: an array of {ty}, which has no size"
                ));
            }
            total = total.saturating_add(s.saturating_mul(*n));
        }
        size.insert(name, Some(total));
        Ok(total)
    }
    let mut names: Vec<&String> = formats.keys().collect();
    names.sort();
    for name in names {
        if let Err(e) = sized(name, 0, &formats, &mut size) {
            return Some(e);
        }
    }
    None
}
