//! CLIP's byte-level BPE tokenizer: clean-up ([`crate::clean`]), the word
//! regex, bytes to printable characters, BPE with an end-of-word marker,
//! start and end tokens, and a fixed context with truncation.

use std::collections::HashMap;

use regex::Regex;

use crate::clean::clean;

/// The word regex of CLIP's tokenizer (matched on lower-cased text).
const WORD_PATTERN: &str = r"(?i)'s|'t|'re|'ve|'m|'ll|'d|\p{L}+|\p{N}|[^\s\p{L}\p{N}]+";

/// Start-of-text token as Hugging Face's files spell it.
pub const START_OF_TEXT: &str = "<|startoftext|>";
/// End-of-text token as Hugging Face's files spell it.
pub const END_OF_TEXT: &str = "<|endoftext|>";
/// The end-of-word marker appended to a word's last symbol.
const END_OF_WORD: &str = "</w>";

/// A vocabulary or merge list that does not make a CLIP tokenizer.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct VocabError(pub String);

/// CLIP's tokenizer over one vocabulary and merge list.
#[derive(Debug, Clone)]
pub struct ClipTokenizer {
    encoder: HashMap<String, u32>,
    ranks: HashMap<(String, String), usize>,
    byte_chars: [char; 256],
    words: Regex,
    start: u32,
    end: u32,
    context_length: usize,
}

/// GPT-2's map from bytes to printable characters: printable Latin-1 bytes
/// map to themselves, the others to `U+0100` onwards in byte order.
pub fn byte_chars() -> [char; 256] {
    let printable = |b: u32| {
        (0x21..=0x7e).contains(&b) || (0xa1..=0xac).contains(&b) || (0xae..=0xff).contains(&b)
    };
    let mut out = ['\0'; 256];
    let mut next = 256;
    for (b, slot) in out.iter_mut().enumerate() {
        let b = b as u32;
        let code = if printable(b) {
            b
        } else {
            next += 1;
            next - 1
        };
        *slot = char::from_u32(code).unwrap_or('\u{fffd}');
    }
    out
}

/// The byte symbols in the order of the original vocabulary (ids 0 to
/// 255): the printable bytes, then the others, which is code point order.
pub fn byte_symbols_in_vocab_order() -> Vec<char> {
    let mut chars = byte_chars().to_vec();
    chars.sort_unstable();
    chars
}

impl ClipTokenizer {
    /// A tokenizer from a token-to-id map (which must hold the start and end
    /// tokens, [`START_OF_TEXT`] and [`END_OF_TEXT`], or OpenCLIP's
    /// `<start_of_text>` and `<end_of_text>`) and the merges in rank
    /// order, padding/truncating to `context_length` tokens.
    pub fn new(
        encoder: HashMap<String, u32>,
        merges: Vec<(String, String)>,
        context_length: usize,
    ) -> Result<Self, VocabError> {
        // OpenCLIP's own spelling of the special tokens is accepted too.
        let id = |t: &str, alt: &str| {
            encoder
                .get(t)
                .or_else(|| encoder.get(alt))
                .copied()
                .ok_or_else(|| VocabError(format!("the vocabulary has no {t} token")))
        };
        let start = id(START_OF_TEXT, "<start_of_text>")?;
        let end = id(END_OF_TEXT, "<end_of_text>")?;
        if context_length < 2 {
            return Err(VocabError(format!(
                "a context of {context_length} tokens cannot hold the start and end tokens"
            )));
        }
        let words = Regex::new(WORD_PATTERN).map_err(|e| VocabError(e.to_string()))?;
        let ranks = merges
            .into_iter()
            .enumerate()
            .map(|(i, m)| (m, i))
            .collect();
        Ok(Self {
            encoder,
            ranks,
            byte_chars: byte_chars(),
            words,
            start,
            end,
            context_length,
        })
    }

    /// The original vocabulary from OpenAI's / OpenCLIP's
    /// `bpe_simple_vocab_16e6.txt` (its text): the 256 byte symbols, the
    /// same with the end-of-word marker, the first 48,894 merges, and the
    /// start and end tokens (ids 49406 and 49407).
    pub fn from_open_clip_bpe(text: &str, context_length: usize) -> Result<Self, VocabError> {
        let lines: Vec<&str> = text.split('\n').collect();
        let n_merges = 49152 - 256 - 2;
        if lines.len() < n_merges + 1 {
            return Err(VocabError(format!(
                "{} lines, expected a version line and at least {n_merges} merges",
                lines.len()
            )));
        }
        let merges = lines[1..=n_merges]
            .iter()
            .map(|l| parse_merge(l))
            .collect::<Result<Vec<_>, _>>()?;
        let bytes = byte_symbols_in_vocab_order();
        let mut vocab: Vec<String> = bytes.iter().map(|c| c.to_string()).collect();
        vocab.extend(bytes.iter().map(|c| format!("{c}{END_OF_WORD}")));
        vocab.extend(merges.iter().map(|(a, b)| format!("{a}{b}")));
        vocab.push(START_OF_TEXT.into());
        vocab.push(END_OF_TEXT.into());
        let encoder = vocab.into_iter().zip(0u32..).collect();
        Self::new(encoder, merges, context_length)
    }

    /// Parses a `merges.txt` (a `#version` line, then `a b` per line).
    pub fn parse_merges(text: &str) -> Result<Vec<(String, String)>, VocabError> {
        text.lines()
            .filter(|l| !l.starts_with("#version") && !l.trim().is_empty())
            .map(parse_merge)
            .collect()
    }

    /// Context length: every encoding has at most this many tokens.
    pub fn context_length(&self) -> usize {
        self.context_length
    }

    /// Start-of-text id.
    pub fn start_id(&self) -> u32 {
        self.start
    }

    /// End-of-text id.
    pub fn end_id(&self) -> u32 {
        self.end
    }

    /// The largest id of the vocabulary.
    pub fn max_id(&self) -> u32 {
        self.encoder.values().copied().max().unwrap_or(0)
    }

    /// The BPE ids of `text`'s words, without start or end token and
    /// without truncation.
    pub fn encode_words(&self, text: &str) -> Result<Vec<u32>, VocabError> {
        let cleaned = clean(text);
        let mut ids = Vec::new();
        for word in self.words.find_iter(&cleaned) {
            let symbols: String = word
                .as_str()
                .bytes()
                .map(|b| self.byte_chars[b as usize])
                .collect();
            for token in self.bpe(&symbols) {
                let id = self.encoder.get(&token).ok_or_else(|| {
                    VocabError(format!(
                        "the vocabulary has no token {token:?} (from the word {:?})",
                        word.as_str()
                    ))
                })?;
                ids.push(*id);
            }
        }
        Ok(ids)
    }

    /// `[start] + words + [end]`, truncated to the context length with the
    /// end token kept last.
    pub fn encode(&self, text: &str) -> Result<Vec<u32>, VocabError> {
        let mut ids = vec![self.start];
        ids.extend(self.encode_words(text)?);
        ids.truncate(self.context_length - 1);
        ids.push(self.end);
        Ok(ids)
    }

    /// Byte-pair merging of one word (already in byte symbols): the merge of
    /// lowest rank is applied everywhere until none applies.
    fn bpe(&self, word: &str) -> Vec<String> {
        let chars: Vec<char> = word.chars().collect();
        let Some((last, init)) = chars.split_last() else {
            return Vec::new();
        };
        let mut parts: Vec<String> = init.iter().map(|c| c.to_string()).collect();
        parts.push(format!("{last}{END_OF_WORD}"));
        loop {
            let best = parts
                .windows(2)
                .filter_map(|p| {
                    self.ranks
                        .get(&(p[0].clone(), p[1].clone()))
                        .map(|&r| (r, p[0].clone(), p[1].clone()))
                })
                .min();
            let Some((_, first, second)) = best else {
                break;
            };
            let mut merged = Vec::with_capacity(parts.len());
            let mut i = 0;
            while i < parts.len() {
                if i + 1 < parts.len() && parts[i] == first && parts[i + 1] == second {
                    merged.push(format!("{first}{second}"));
                    i += 2;
                } else {
                    merged.push(std::mem::take(&mut parts[i]));
                    i += 1;
                }
            }
            parts = merged;
            if parts.len() == 1 {
                break;
            }
        }
        parts
    }
}

fn parse_merge(line: &str) -> Result<(String, String), VocabError> {
    let mut it = line.split_whitespace();
    match (it.next(), it.next(), it.next()) {
        (Some(a), Some(b), None) => Ok((a.to_string(), b.to_string())),
        _ => Err(VocabError(format!(
            "bad merge line {line:?} (expected two symbols)"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A handmade vocabulary: bytes, and merges making "lo", "low</w>".
    fn tiny() -> ClipTokenizer {
        let bytes = byte_symbols_in_vocab_order();
        let mut vocab: Vec<String> = bytes.iter().map(|c| c.to_string()).collect();
        vocab.extend(bytes.iter().map(|c| format!("{c}</w>")));
        let merges = vec![
            ("l".to_string(), "o".to_string()),
            ("w".to_string(), "</w>".to_string()),
            ("lo".to_string(), "w</w>".to_string()),
        ];
        vocab.extend(["lo", "w</w>", "low</w>", START_OF_TEXT, END_OF_TEXT].map(String::from));
        let encoder = vocab.into_iter().zip(0u32..).collect();
        ClipTokenizer::new(encoder, merges, 6).expect("tokenizer")
    }

    #[test]
    fn byte_symbols_are_gpt2s() {
        let b = byte_chars();
        assert_eq!(b[b'a' as usize], 'a');
        assert_eq!(b[b' ' as usize], 'Ġ');
        assert_eq!(b[0], 'Ā');
        let mut sorted: Vec<char> = b.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 256);
    }

    #[test]
    fn merges_by_rank_and_truncates_keeping_the_end() {
        let t = tiny();
        let (lo, low) = (512, 514);
        // 'l' is the 76th printable byte symbol ('!' is the first).
        let l_end = 256 + (b'l' - b'!') as u32;
        let (s, e) = (t.start_id(), t.end_id());
        assert_eq!(t.encode("LOW").unwrap(), vec![s, low, e]);
        // "lol": l o l</w> -> lo l</w> (no merge makes "lol").
        assert_eq!(t.encode("lol").unwrap(), vec![s, lo, l_end, e]);
        // Six tokens at most: start, four words, end.
        let ids = t.encode("low low low low low low").unwrap();
        assert_eq!(ids, vec![s, low, low, low, low, e]);
        assert_eq!(t.encode("").unwrap(), vec![s, e]);
    }

    #[test]
    fn missing_special_tokens_and_bad_merges_are_refused() {
        let e = ClipTokenizer::new(HashMap::new(), Vec::new(), 77).unwrap_err();
        assert!(e.0.contains(START_OF_TEXT), "{e}");
        assert!(ClipTokenizer::parse_merges("#version: 0.2\na b c\n").is_err());
        assert_eq!(
            ClipTokenizer::parse_merges("#version: 0.2\na b\n").unwrap(),
            vec![("a".to_string(), "b".to_string())]
        );
    }
}
