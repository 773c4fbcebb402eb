//! Numeric top-level fields of JSON messages, read without building a `serde_json::Value`.
//!
//! A message is walked once by a serde visitor that hands each top-level `(key, number)` pair to a
//! callback and skips every other value; keys are borrowed from the message where they have no
//! escapes, so the hot path allocates nothing.

use std::borrow::Cow;
use std::fmt;
use std::ops::Range;

use serde::de::{self, DeserializeSeed, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde_json::value::RawValue;

/// Calls `field(key, value)` for every top-level field of the JSON object in `data`, with
/// `Some(number)` for numeric values and `None` for others. A message that is not a JSON object,
/// and any error `field` returns, ends the walk with that error's text.
pub(crate) fn for_each_field<F>(data: &[u8], field: F) -> Result<(), String>
where
    F: FnMut(&str, Option<f64>) -> Result<(), String>,
{
    let mut de = serde_json::Deserializer::from_slice(data);
    Fields(field)
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|e| {
            if e.is_data() {
                // Our own messages (from `field`, or "not an object") come back as data errors.
                strip_position(&e)
            } else {
                format!("the message is not valid JSON ({e})")
            }
        })
}

/// The byte ranges in `data` of the values of the top-level fields named `key` (normally one;
/// JSON allows a key twice, and a reader keeps the last), for rewriting them in place. Errors as
/// [`for_each_field`].
pub(crate) fn field_spans(data: &[u8], key: &str) -> Result<Vec<Range<usize>>, String> {
    let mut de = serde_json::Deserializer::from_slice(data);
    let mut spans = Vec::new();
    Spans {
        key,
        base: data.as_ptr() as usize,
        out: &mut spans,
    }
    .deserialize(&mut de)
    .and_then(|()| de.end())
    .map_err(|e| {
        if e.is_data() {
            strip_position(&e)
        } else {
            format!("the message is not valid JSON ({e})")
        }
    })?;
    Ok(spans)
}

struct Spans<'k, 'o> {
    key: &'k str,
    /// Address of the message's first byte: a borrowed raw value's offset is its address minus
    /// this.
    base: usize,
    out: &'o mut Vec<Range<usize>>,
}

impl<'de> DeserializeSeed<'de> for Spans<'_, '_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for Spans<'_, '_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON object with one numeric field per channel")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key_seed(Key)? {
            let raw: &'de RawValue = map.next_value()?;
            if key == self.key {
                let start = raw.get().as_ptr() as usize - self.base;
                self.out.push(start..start + raw.get().len());
            }
        }
        Ok(())
    }
}

/// serde_json appends " at line L column C" to custom errors; for our messages it is noise.
fn strip_position(e: &serde_json::Error) -> String {
    let text = e.to_string();
    match text.rfind(" at line ") {
        Some(i) => text[..i].to_string(),
        None => text,
    }
}

struct Fields<F>(F);

impl<'de, F> DeserializeSeed<'de> for Fields<F>
where
    F: FnMut(&str, Option<f64>) -> Result<(), String>,
{
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de, F> Visitor<'de> for Fields<F>
where
    F: FnMut(&str, Option<f64>) -> Result<(), String>,
{
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON object with one numeric field per channel")
    }
    fn visit_map<A: MapAccess<'de>>(mut self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key_seed(Key)? {
            let value = map.next_value_seed(Number)?;
            (self.0)(&key, value).map_err(de::Error::custom)?;
        }
        Ok(())
    }
}

/// A map key, borrowed where the JSON text allows.
struct Key;

impl<'de> DeserializeSeed<'de> for Key {
    type Value = Cow<'de, str>;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_str(self)
    }
}

impl<'de> Visitor<'de> for Key {
    type Value = Cow<'de, str>;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a field name")
    }
    fn visit_borrowed_str<E: de::Error>(self, v: &'de str) -> Result<Self::Value, E> {
        Ok(Cow::Borrowed(v))
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Self::Value, E> {
        Ok(Cow::Owned(v.to_string()))
    }
    fn visit_string<E: de::Error>(self, v: String) -> Result<Self::Value, E> {
        Ok(Cow::Owned(v))
    }
}

/// A value: `Some` if it is a number, `None` (after skipping it) otherwise.
struct Number;

impl<'de> DeserializeSeed<'de> for Number {
    type Value = Option<f64>;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Number {
    type Value = Option<f64>;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("any JSON value")
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Self::Value, E> {
        Ok(Some(v))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Self::Value, E> {
        Ok(Some(v as f64))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Self::Value, E> {
        Ok(Some(v as f64))
    }
    fn visit_bool<E: de::Error>(self, _: bool) -> Result<Self::Value, E> {
        Ok(None)
    }
    fn visit_str<E: de::Error>(self, _: &str) -> Result<Self::Value, E> {
        Ok(None)
    }
    fn visit_unit<E: de::Error>(self) -> Result<Self::Value, E> {
        Ok(None)
    }
    fn visit_none<E: de::Error>(self) -> Result<Self::Value, E> {
        Ok(None)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        Ok(None)
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fields(json: &str) -> Result<Vec<(String, Option<f64>)>, String> {
        let mut out = Vec::new();
        for_each_field(json.as_bytes(), |k, v| {
            out.push((k.to_string(), v));
            Ok(())
        })?;
        Ok(out)
    }

    #[test]
    fn numbers_are_kept_in_order_and_others_skipped() {
        let got = fields(
            r#"{"b": 1.5, "s": "x", "a": -2, "n": null, "o": {"c": 1}, "l": [1, 2], "u": 7}"#,
        )
        .unwrap();
        let want = [
            ("b", Some(1.5)),
            ("s", None),
            ("a", Some(-2.0)),
            ("n", None),
            ("o", None),
            ("l", None),
            ("u", Some(7.0)),
        ];
        assert_eq!(got.len(), want.len());
        for ((k, v), (wk, wv)) in got.iter().zip(want) {
            assert_eq!((k.as_str(), *v), (wk, wv));
        }
        assert_eq!(fields(r#"{"a\u0062": 1}"#).unwrap()[0].0, "ab");
    }

    #[test]
    fn spans_cover_exactly_the_value() {
        let data = br#"{ "b" : 1.5 , "a":-2e3,"o":{"a":7}, "a" : 12 }"#;
        let spans = field_spans(data, "a").unwrap();
        let texts: Vec<&[u8]> = spans.iter().map(|r| &data[r.clone()]).collect();
        assert_eq!(texts, [&b"-2e3"[..], &b"12"[..]]);
        assert!(field_spans(data, "z").unwrap().is_empty());
        // Escaped keys are compared unescaped.
        let data = br#"{"\u0061": 3}"#;
        let spans = field_spans(data, "a").unwrap();
        assert_eq!(spans, vec![Range { start: 11, end: 12 }]);
        assert!(
            field_spans(b"[1]", "a")
                .unwrap_err()
                .contains("JSON object")
        );
    }

    #[test]
    fn bad_messages_are_errors() {
        assert!(fields("[1, 2]").unwrap_err().contains("JSON object"));
        assert!(fields(r#"{"a": 1"#).unwrap_err().contains("not valid JSON"));
        assert!(
            fields(r#"{"a": 1} x"#)
                .unwrap_err()
                .contains("not valid JSON")
        );
        let err = for_each_field(br#"{"a": 1}"#, |_, _| Err("boom".into())).unwrap_err();
        assert_eq!(err, "boom");
    }
}
