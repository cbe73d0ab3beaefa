//! Text clean-up before tokenising, as OpenAI's and OpenCLIP's tokenizer do
//! it: `ftfy.fix_text`, HTML unescaping, whitespace collapsing and
//! lower-casing.
//!
//! Of `ftfy` this implements the fixes that change ordinary typed text:
//! Latin ligatures (`ﬁ` -> `fi`), full-width characters (`ＡＢＣ` -> `ABC`),
//! curly quotes (`’` -> `'`), control characters, and NFC normalisation. It
//! does not repair mojibake (text decoded with the wrong encoding) or C1
//! control characters. HTML unescaping covers numeric references and the
//! common named entities (`&amp;`, `&lt;`, `&gt;`, `&quot;`, `&apos;`,
//! `&nbsp;` and some punctuation), not all of HTML5's 2,231 names.

use unicode_normalization::UnicodeNormalization;

/// The cleaned, lower-cased text the tokenizer splits into words.
pub fn clean(text: &str) -> String {
    // ftfy unescapes HTML (to a fixed point, as it repeats its fixes) unless
    // the text looks like markup; OpenCLIP then unescapes twice more.
    let mut t = if text.contains('<') {
        text.to_string()
    } else {
        unescape_to_fixed_point(text)
    };
    t = fix_text(&t);
    t = html_unescape(&html_unescape(&t));
    whitespace_clean(&t).to_lowercase()
}

/// Whether Python's `str.isspace` holds (Unicode whitespace plus the
/// ASCII information separators).
fn is_space(c: char) -> bool {
    c.is_whitespace() || ('\u{1c}'..='\u{1f}').contains(&c)
}

/// Runs of whitespace become one space; leading and trailing whitespace goes.
pub fn whitespace_clean(text: &str) -> String {
    text.split(is_space)
        .filter(|w| !w.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// The `ftfy` fixes listed in the module docs, then NFC.
fn fix_text(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        let code = c as u32;
        match c {
            _ if is_control(code) => {}
            _ if ligature(c).is_some() => out.push_str(ligature(c).unwrap_or_default()),
            '\u{3000}' => out.push(' '),
            '\u{ff01}'..='\u{ffef}' => out.extend(c.to_string().nfkc()),
            '\u{02bc}' | '\u{2018}'..='\u{201b}' => out.push('\''),
            '\u{201c}'..='\u{201f}' => out.push('"'),
            _ => out.push(c),
        }
    }
    out.nfc().collect()
}

/// `ftfy`'s control characters (removed).
fn is_control(code: u32) -> bool {
    matches!(code, 0x00..=0x08 | 0x0b | 0x0e..=0x1f | 0x7f | 0x206a..=0x206f | 0xfeff | 0xfff9..=0xfffc)
}

/// `ftfy`'s Latin ligatures, spelled out.
fn ligature(c: char) -> Option<&'static str> {
    Some(match c {
        'Ĳ' => "IJ",
        'ĳ' => "ij",
        'ŉ' => "'n",
        'Ǆ' => "DŽ",
        'ǅ' => "Dž",
        'ǆ' => "dž",
        'Ǉ' => "LJ",
        'ǈ' => "Lj",
        'ǉ' => "lj",
        'Ǌ' => "NJ",
        'ǋ' => "Nj",
        'ǌ' => "nj",
        'Ǳ' => "DZ",
        'ǲ' => "Dz",
        'ǳ' => "dz",
        'ﬀ' => "ff",
        'ﬁ' => "fi",
        'ﬂ' => "fl",
        'ﬃ' => "ffi",
        'ﬄ' => "ffl",
        'ﬅ' => "ſt",
        'ﬆ' => "st",
        _ => return None,
    })
}

fn unescape_to_fixed_point(text: &str) -> String {
    let mut t = text.to_string();
    for _ in 0..8 {
        let u = html_unescape(&t);
        if u == t {
            break;
        }
        t = u;
    }
    t
}

/// The named entities decoded (with a `;`; the first four also without).
const ENTITIES: &[(&str, &str)] = &[
    ("amp", "&"),
    ("lt", "<"),
    ("gt", ">"),
    ("quot", "\""),
    ("apos", "'"),
    ("nbsp", "\u{a0}"),
    ("copy", "©"),
    ("reg", "®"),
    ("trade", "™"),
    ("hellip", "…"),
    ("ndash", "–"),
    ("mdash", "—"),
    ("lsquo", "‘"),
    ("rsquo", "’"),
    ("ldquo", "“"),
    ("rdquo", "”"),
    ("laquo", "«"),
    ("raquo", "»"),
    ("deg", "°"),
    ("times", "×"),
    ("middot", "·"),
    ("euro", "€"),
    ("pound", "£"),
];

/// One pass of HTML character-reference decoding (like Python's
/// `html.unescape` on the references it knows).
pub fn html_unescape(text: &str) -> String {
    if !text.contains('&') {
        return text.to_string();
    }
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find('&') {
        out.push_str(&rest[..at]);
        rest = &rest[at..];
        match decode_reference(&rest[1..]) {
            Some((decoded, used)) => {
                out.push_str(&decoded);
                rest = &rest[1 + used..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

/// The text of the reference at the start of `s` (after `&`) and the bytes
/// it spans.
fn decode_reference(s: &str) -> Option<(String, usize)> {
    if let Some(num) = s.strip_prefix('#') {
        let (digits, radix, skip) = match num.strip_prefix(['x', 'X']) {
            Some(hex) => (hex, 16, 2),
            None => (num, 10, 1),
        };
        let len = digits
            .char_indices()
            .find(|(_, c)| !c.is_digit(radix))
            .map_or(digits.len(), |(i, _)| i);
        if len == 0 {
            return None;
        }
        let value = u32::from_str_radix(&digits[..len], radix).unwrap_or(u32::MAX);
        let c = match value {
            0 | 0xd800..=0xdfff | 0x110000.. => '\u{fffd}',
            v => char::from_u32(v).unwrap_or('\u{fffd}'),
        };
        let semi = usize::from(digits[len..].starts_with(';'));
        return Some((c.to_string(), skip + len + semi));
    }
    for (name, value) in ENTITIES {
        if let Some(after) = s.strip_prefix(name) {
            if after.starts_with(';') {
                return Some((value.to_string(), name.len() + 1));
            }
            if ["amp", "lt", "gt", "quot"].contains(name) {
                return Some((value.to_string(), name.len()));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cleans_like_open_clip() {
        assert_eq!(clean("  Wooden \t\n TABLE  "), "wooden table");
        assert_eq!(clean("Don’t “quote”"), "don't \"quote\"");
        assert_eq!(clean("ﬁsh ＦＵＬＬ"), "fish full");
        assert_eq!(clean("fish &amp; chips &lt;3"), "fish & chips <3");
        assert_eq!(clean("&amp;amp;lt;"), "<");
        assert_eq!(clean("&#233;t&#xE9; &#0;"), "été \u{fffd}");
        assert_eq!(clean("cafe\u{301}"), "café");
        assert_eq!(clean("a\u{0}b\u{feff}c"), "abc");
        assert_eq!(clean("&unknown; & amp"), "&unknown; & amp");
    }
}
