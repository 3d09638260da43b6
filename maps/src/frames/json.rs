//! Reading the values of a frame line's JSON, with messages that name the field
//! (`detections[2].p_rover: expected 3 numbers, got 2`).

use serde_json::{Map, Value};

use crate::error::{snippet, LineError};

/// A required field.
pub(super) fn required<'a>(
    object: &'a Map<String, Value>,
    key: &str,
) -> Result<&'a Value, LineError> {
    object
        .get(key)
        .ok_or_else(|| format!("\"{key}\" is missing").into())
}

/// An optional field (absent or `null` = not given).
pub(super) fn optional<'a>(object: &'a Map<String, Value>, key: &str) -> Option<&'a Value> {
    object.get(key).filter(|v| !v.is_null())
}

/// A finite number.
pub(super) fn number(value: &Value, field: &str) -> Result<f64, LineError> {
    match value.as_f64() {
        Some(v) if v.is_finite() => Ok(v),
        Some(v) => Err(format!("{field}: {v} is not a finite number").into()),
        None => Err(format!("{field}: expected a number, got {}", describe(value)).into()),
    }
}

/// An array.
pub(super) fn array<'a>(value: &'a Value, field: &str) -> Result<&'a [Value], LineError> {
    value
        .as_array()
        .map(Vec::as_slice)
        .ok_or_else(|| format!("{field}: expected an array, got {}", describe(value)).into())
}

/// An array of exactly `N` finite numbers.
pub(super) fn numbers<const N: usize>(value: &Value, field: &str) -> Result<[f64; N], LineError> {
    let items = array(value, field)?;
    if items.len() != N {
        return Err(format!("{field}: expected {N} numbers, got {}", items.len()).into());
    }
    let mut out = [0.0; N];
    for (k, (slot, item)) in out.iter_mut().zip(items).enumerate() {
        *slot = number(item, &format!("{field}[{k}]"))?;
    }
    Ok(out)
}

/// A JSON value for a message: its kind and (shortened) text.
pub(super) fn describe(value: &Value) -> String {
    let kind = match value {
        Value::Null => return "null".to_string(),
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    };
    format!("{kind} {}", snippet(&value.to_string(), 40))
}

/// A serde_json error on one line, in plain words (the line number is added by the caller);
/// `json` is the text given to serde_json, `lead` the number of bytes before it on the line.
pub(super) fn json_message(e: &serde_json::Error, json: &str, lead: usize) -> String {
    use serde_json::error::Category;
    let full = e.to_string();
    // serde_json appends " at line L column C"; the line is always 1 here
    let what = full
        .rsplit_once(" at line ")
        .map_or(full.as_str(), |(head, _)| head);
    let column = e.column() + lead;
    match e.classify() {
        Category::Eof => format!("the JSON ends early (truncated line?): {what} (column {column})"),
        // serde_json refuses a number beyond f64 (1e999) rather than reading infinity
        Category::Syntax if what == "number out of range" => format!(
            "number {} (column {column}) is out of range; every value must be finite",
            number_at(json, e.column())
        ),
        _ => format!("JSON syntax error: {what} (column {column})"),
    }
}

/// The number that ends at or runs through 1-based byte `column` of `json`, for a message.
fn number_at(json: &str, column: usize) -> String {
    let is_number = |b: &u8| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E');
    let bytes = json.as_bytes();
    let at = column.min(bytes.len());
    let start = bytes[..at]
        .iter()
        .rposition(|b| !is_number(b))
        .map_or(0, |k| k + 1);
    let end = bytes[at..]
        .iter()
        .position(|b| !is_number(b))
        .map_or(bytes.len(), |k| at + k);
    // only ASCII bytes were taken, so the range is on character boundaries
    snippet(json.get(start..end).unwrap_or(""), 30)
}
