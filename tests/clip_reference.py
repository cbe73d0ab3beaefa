#!/usr/bin/env python3
"""Reference outputs for the Rust CLIP text encoder and tokenizer.

Writes, under OUT (default: clip/tests/fixtures next to this script's parent):

  hf_tiny/        a randomly initialised Hugging Face CLIPTextModelWithProjection
                  (width 32, 2 layers, 4 heads, quick-GELU, eos-id pooling):
                  model.safetensors, config.json, reference.json
  openclip_tiny/  the text tower of a randomly initialised OpenCLIP CLIP model
                  (width 32, 2 layers, 4 heads, exact GELU, argmax pooling),
                  stored in float16: open_clip_model.safetensors,
                  open_clip_config.json, reference.json
  tokenizer/      the part of the real CLIP BPE vocabulary (from open_clip's
                  bpe_simple_vocab_16e6.txt.gz) that the tricky strings need,
                  as vocab.json + merges.txt with the original ids, and
                  expected.json: the ids open_clip's tokenizer and Hugging
                  Face's CLIPTokenizer give each string with the full vocabulary

With --full-size, writes instead (about 750 MB, not checked in) a random
Hugging Face CLIPModel with the text tower of CLIP ViT-L/14 (width 768, 12
layers, 12 heads, 768-d) and a tiny vision tower, the full CLIP vocabulary
as vocab.json + merges.txt, and reference.json: the texts and their
normalised embeddings, end to end through CLIPTokenizer and the model; and
the same for a random OpenCLIP ViT-B-32-quickgelu text tower with
open_clip_config.json, bpe_simple_vocab_16e6.txt.gz and open_clip's tokenizer.

Needs torch, transformers, open_clip_torch and ftfy. Deterministic (seeded).

    python3 tests/clip_reference.py [OUT]
    python3 tests/clip_reference.py --full-size OUT
"""

import gzip
import json
import os
import sys

import torch

TRICKY = [
    "a photo of a chair",
    "Something to SIT on",
    "  wooden   table\t\n with  legs  ",
    "don't touch: it's the cat's toy, isn't it?",
    "Don’t use curly “quotes”",
    "3.14159 apples and 42 pears, 1,000,000 grains",
    "café naïve résumé Ångström",
    "Straße, Ελληνικά, русский, 日本語のテキスト",
    "pizza 🍕 and a cat 🐱‍👤!!!",
    "mixedCASE WoRdS with-hyphens and_underscores",
    "e-mail: someone@example.com #hashtag $5 100%",
    "ﬁsh ﬂour ＦＵＬＬＷＩＤＴＨ",
    "fish &amp; chips &lt;3",
    "<|endoftext|> inside text",
    "",
    "...",
    "soft",
    "something to sit on " * 25,
]

CONTEXT = 77

# The tiny Hugging Face text tower (also the text side of the vision
# reference's tiny CLIPModel).
HF_TINY_TEXT = dict(
    vocab_size=48,
    hidden_size=32,
    intermediate_size=64,
    projection_dim=16,
    num_hidden_layers=2,
    num_attention_heads=4,
    max_position_embeddings=16,
    hidden_act="quick_gelu",
    layer_norm_eps=1e-5,
    bos_token_id=46,
    eos_token_id=45,
    pad_token_id=1,
)


def out_dir():
    if len(sys.argv) > 1:
        return sys.argv[1]
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.join(here, "..", "clip", "tests", "fixtures")


def save_json(path, value):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(value, f, ensure_ascii=False, indent=1)
        f.write("\n")


def flat(t):
    return [round(float(x), 7) for x in t.detach().reshape(-1).tolist()]


def hf_model(out):
    import transformers
    from transformers import CLIPTextConfig, CLIPTextModelWithProjection

    torch.manual_seed(0)
    config = CLIPTextConfig(**HF_TINY_TEXT)
    model = CLIPTextModelWithProjection(config).eval()
    # Default init leaves biases and norms at 0 / 1: perturb every parameter
    # so that a misplaced bias or norm weight shows.
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.05 * torch.randn_like(p))
    d = os.path.join(out, "hf_tiny")
    os.makedirs(d, exist_ok=True)
    model.save_pretrained(d, safe_serialization=True)
    # 47 (above the eos id 45) before the end: eos-id pooling and argmax
    # pooling disagree on the first sequence.
    ids = torch.tensor(
        [
            [46, 7, 47, 12, 9, 45, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1],
            [46, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 45],
            [46, 45, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1],
        ]
    )
    with torch.no_grad():
        o = model(input_ids=ids)
    save_json(
        os.path.join(d, "reference.json"),
        {
            "generator": f"transformers {transformers.__version__}, torch {torch.__version__}",
            "input_ids": ids.tolist(),
            "text_embeds": flat(o.text_embeds),
            "last_hidden_state": flat(o.last_hidden_state),
        },
    )


def openclip_model(out):
    import open_clip
    from open_clip.model import CLIP
    from safetensors.torch import save_file

    torch.manual_seed(1)
    text_cfg = dict(context_length=16, vocab_size=40, width=32, heads=4, layers=2)
    vision_cfg = dict(image_size=16, patch_size=8, width=32, layers=1, head_width=16)
    model = CLIP(embed_dim=16, vision_cfg=vision_cfg, text_cfg=text_cfg, quick_gelu=False).eval()
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.05 * torch.randn_like(p))
    state = {
        k: v.detach().to(torch.float16).contiguous()
        for k, v in model.state_dict().items()
        if not k.startswith("visual.")
    }
    # The reference runs on the weights as stored (rounded to float16).
    model.load_state_dict({k: v.float() for k, v in state.items()}, strict=False)
    d = os.path.join(out, "openclip_tiny")
    os.makedirs(d, exist_ok=True)
    save_file(state, os.path.join(d, "open_clip_model.safetensors"))
    save_json(
        os.path.join(d, "open_clip_config.json"),
        {"model_cfg": {"embed_dim": 16, "quick_gelu": False, "text_cfg": text_cfg}},
    )
    ids = torch.tensor(
        [
            [38, 5, 6, 7, 39, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
            [38, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 39],
        ]
    )
    with torch.no_grad():
        emb = model.encode_text(ids)
    save_json(
        os.path.join(d, "reference.json"),
        {
            "generator": f"open_clip_torch {open_clip.__version__}, torch {torch.__version__}",
            "input_ids": ids.tolist(),
            "text_embeds": flat(emb),
        },
    )


def bpe_trace(bpe_ranks, token):
    """The merges open_clip's BPE applies to one pre-token, in order."""
    word = tuple(token[:-1]) + (token[-1] + "</w>",)
    used = []
    while len(word) > 1:
        pairs = {(word[i], word[i + 1]) for i in range(len(word) - 1)}
        best = min(pairs, key=lambda p: bpe_ranks.get(p, float("inf")))
        if best not in bpe_ranks:
            break
        used.append(best)
        first, second = best
        new, i = [], 0
        while i < len(word):
            if i < len(word) - 1 and word[i] == first and word[i + 1] == second:
                new.append(first + second)
                i += 2
            else:
                new.append(word[i])
                i += 1
        word = tuple(new)
    return used


def tokenizer_fixture(out):
    import ftfy
    import open_clip
    import transformers
    from open_clip.tokenizer import SimpleTokenizer, bytes_to_unicode, default_bpe
    from transformers import CLIPTokenizer

    simple = SimpleTokenizer()
    full_ids = simple(TRICKY, context_length=CONTEXT).tolist()
    open_clip_ids = [[t for t in row if t != 0] for row in full_ids]

    # The full vocabulary as vocab.json / merges.txt, for Hugging Face.
    d = os.path.join(out, "tokenizer")
    os.makedirs(d, exist_ok=True)
    tmp = os.path.join(d, "_full")
    os.makedirs(tmp, exist_ok=True)
    merges = gzip.open(default_bpe()).read().decode("utf-8").split("\n")
    merges = [tuple(m.split()) for m in merges[1 : 49152 - 256 - 2 + 1]]
    # Hugging Face's files name the special tokens <|startoftext|> and
    # <|endoftext|> (open_clip calls them <start_of_text>, <end_of_text>).
    rename = {"<start_of_text>": "<|startoftext|>", "<end_of_text>": "<|endoftext|>"}
    encoder = {rename.get(t, t): i for t, i in simple.encoder.items()}
    save_json(os.path.join(tmp, "vocab.json"), encoder)
    with open(os.path.join(tmp, "merges.txt"), "w", encoding="utf-8") as f:
        f.write("#version: 0.2\n")
        for a, b in merges:
            f.write(f"{a} {b}\n")
    hf = CLIPTokenizer(os.path.join(tmp, "vocab.json"), os.path.join(tmp, "merges.txt"))
    hf_ids = [hf(t, truncation=True, max_length=CONTEXT)["input_ids"] for t in TRICKY]

    # The merges these strings use (after either library's clean-up), and
    # every token they produce, keep their ranks and ids: BPE on the reduced
    # vocabulary gives the same ids.
    from open_clip.tokenizer import basic_clean, whitespace_clean

    ranks = dict(zip(merges, range(len(merges))))
    used = set()
    byte_encoder = bytes_to_unicode()
    backend = hf.backend_tokenizer
    for text in TRICKY:
        cleaned = whitespace_clean(basic_clean(text)).lower()
        words = [
            "".join(byte_encoder[b] for b in token.encode("utf-8"))
            for token in simple.pat.findall(cleaned)
        ]
        normalized = backend.normalizer.normalize_str(text)
        words += [w for w, _ in backend.pre_tokenizer.pre_tokenize_str(normalized)]
        for word in words:
            if word not in encoder or len(word) > 1:
                used.update(bpe_trace(ranks, word))
    kept = sorted(used, key=lambda m: ranks[m])
    base = list(bytes_to_unicode().values())
    keep_tokens = set(base) | {v + "</w>" for v in base} | {"".join(m) for m in kept}
    keep_tokens |= {"<|startoftext|>", "<|endoftext|>"}
    vocab = {t: i for t, i in encoder.items() if t in keep_tokens}
    save_json(os.path.join(d, "vocab.json"), vocab)
    with open(os.path.join(d, "merges.txt"), "w", encoding="utf-8") as f:
        f.write("#version: 0.2 (the merges of the CLIP BPE vocabulary that the tricky strings use)\n")
        for a, b in kept:
            f.write(f"{a} {b}\n")
    small = CLIPTokenizer(os.path.join(d, "vocab.json"), os.path.join(d, "merges.txt"))
    small_ids = [small(t, truncation=True, max_length=CONTEXT)["input_ids"] for t in TRICKY]
    for f in ("vocab.json", "merges.txt"):
        os.remove(os.path.join(tmp, f))
    os.rmdir(tmp)
    cases = []
    for text, a, b, c in zip(TRICKY, open_clip_ids, hf_ids, small_ids):
        cases.append({"text": text, "open_clip": a, "hf": b, "hf_reduced_vocab": c})
    save_json(
        os.path.join(d, "expected.json"),
        {
            "generator": (
                f"open_clip_torch {open_clip.__version__} (ftfy {ftfy.__version__}), "
                f"transformers {transformers.__version__}"
            ),
            "context_length": CONTEXT,
            "cases": cases,
        },
    )
    for case in cases:
        if case["open_clip"] != case["hf"]:
            print(f"open_clip and transformers differ on {case['text']!r}")
        if case["hf"] != case["hf_reduced_vocab"]:
            print(f"the reduced vocabulary changes {case['text']!r}")


def full_vocab(d):
    """The real CLIP vocabulary as Hugging Face's vocab.json + merges.txt."""
    from open_clip.tokenizer import SimpleTokenizer, default_bpe

    simple = SimpleTokenizer()
    rename = {"<start_of_text>": "<|startoftext|>", "<end_of_text>": "<|endoftext|>"}
    save_json(os.path.join(d, "vocab.json"), {rename.get(t, t): i for t, i in simple.encoder.items()})
    merges = gzip.open(default_bpe()).read().decode("utf-8").split("\n")[1 : 49152 - 256 - 2 + 1]
    with open(os.path.join(d, "merges.txt"), "w", encoding="utf-8") as f:
        f.write("#version: 0.2\n")
        for m in merges:
            f.write(m + "\n")


def full_size(out):
    import transformers
    from transformers import CLIPConfig, CLIPModel, CLIPTokenizer

    torch.manual_seed(2)
    text = dict(
        hidden_size=768, intermediate_size=3072, projection_dim=768, num_hidden_layers=12,
        num_attention_heads=12, max_position_embeddings=77, vocab_size=49408,
        hidden_act="quick_gelu", eos_token_id=2,
    )
    vision = dict(
        hidden_size=32, intermediate_size=64, num_hidden_layers=1, num_attention_heads=2,
        image_size=32, patch_size=16, projection_dim=768,
    )
    model = CLIPModel(CLIPConfig(text_config=text, vision_config=vision, projection_dim=768)).eval()
    d = os.path.join(out, "hf_vit_l14")
    os.makedirs(d, exist_ok=True)
    model.save_pretrained(d, safe_serialization=True)
    full_vocab(d)
    tok = CLIPTokenizer(os.path.join(d, "vocab.json"), os.path.join(d, "merges.txt"))
    texts = ["wooden", "soft", "something to sit on", "a photo of a chair", "something to sit on " * 25]
    enc = tok(texts, padding="max_length", truncation=True, max_length=77, return_tensors="pt")
    with torch.no_grad():
        emb = model.get_text_features(input_ids=enc["input_ids"])
        if not torch.is_tensor(emb):
            emb = emb.pooler_output
        emb = emb / emb.norm(dim=-1, keepdim=True)
    save_json(
        os.path.join(d, "reference.json"),
        {
            "generator": f"transformers {transformers.__version__}, torch {torch.__version__}",
            "texts": texts,
            "text_embeds": flat(emb),
        },
    )
    print(f"wrote {os.path.abspath(d)}")
    full_size_open_clip(out)


def full_size_open_clip(out):
    """A random OpenCLIP ViT-B-32-quickgelu text tower (OpenAI's layout),
    with open_clip's own vocabulary file and tokenizer."""
    import shutil

    import open_clip
    from open_clip.tokenizer import SimpleTokenizer, default_bpe
    from safetensors.torch import save_file

    torch.manual_seed(3)
    model = open_clip.create_model("ViT-B-32-quickgelu", pretrained=None).eval()
    cfg = open_clip.get_model_config("ViT-B-32-quickgelu")
    d = os.path.join(out, "open_clip_vit_b32")
    os.makedirs(d, exist_ok=True)
    state = {k: v.contiguous() for k, v in model.state_dict().items() if not k.startswith("visual.")}
    save_file(state, os.path.join(d, "open_clip_model.safetensors"))
    save_json(os.path.join(d, "open_clip_config.json"), {"model_cfg": cfg})
    shutil.copy(default_bpe(), os.path.join(d, "bpe_simple_vocab_16e6.txt.gz"))
    texts = ["wooden", "soft", "something to sit on", "Don’t sit on the “soft” ﬁsh", "something to sit on " * 25]
    with torch.no_grad():
        emb = model.encode_text(SimpleTokenizer()(texts), normalize=True)
    save_json(
        os.path.join(d, "reference.json"),
        {
            "generator": f"open_clip_torch {open_clip.__version__}, torch {torch.__version__}",
            "texts": texts,
            "text_embeds": flat(emb),
        },
    )
    print(f"wrote {os.path.abspath(d)}")


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--full-size":
        full_size(sys.argv[2])
        return
    out = out_dir()
    os.makedirs(out, exist_ok=True)
    hf_model(out)
    openclip_model(out)
    tokenizer_fixture(out)
    print(f"wrote {os.path.abspath(out)}")


if __name__ == "__main__":
    main()
