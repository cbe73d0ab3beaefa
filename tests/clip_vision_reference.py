#!/usr/bin/env python3
"""Reference outputs for the Rust CLIP vision tower: the standard image
embedding, the training-free dense (pixel-aligned) features of the last
block, and the sliding-window dense extraction over an RGB image.

Writes, under OUT (default: clip/tests/fixtures/vision next to this
script's parent):

  hf_tiny/        a randomly initialised Hugging Face CLIPModel with both
                  towers: the text tower of tests/clip_reference.py's
                  hf_tiny (width 32, 2 layers, vocabulary 48) and a vision
                  tower of width 32, 2 layers, 4 heads, quick-GELU, image
                  32, patch 8; projection 16. model.safetensors,
                  config.json, preprocessor_config.json (OpenAI's mean and
                  std, size 32), reference.json
  openclip_tiny/  a randomly initialised OpenCLIP CLIP in OpenAI's layout
                  (quick-GELU, packed in_proj attention, visual.proj a
                  [width, embed_dim] matrix), the same vision tower shape,
                  the text tower of tests/clip_reference.py's openclip_tiny.
                  Both towers in float32: open_clip_model.safetensors,
                  open_clip_config.json (model_cfg and preprocess_cfg),
                  reference.json

Every parameter is perturbed (p += 0.05 * randn) so that a misplaced bias or
norm weight shows. The tokenizer fixture is not copied into hf_tiny: its ids
(up to 49407) do not fit the text tower's 48-token vocabulary.

Each reference.json holds (float arrays flattened row-major, 7 decimals;
shapes in comments here, the Rust test knows them):

  generator       library versions
  native_pixels   [2, 3, 32, 32] seeded normal input (3 decimals)
  image_embeds    [2, 16] the standard tower output on it (not normalised)
  dense_pixels    [1, 3, 40, 56] seeded normal input (3 decimals): a 5 x 7
                  patch grid, so the position embeddings are interpolated
                  (bicubic, align_corners=False) from the native 4 x 4
  dense           {"naclip", "clearclip", "maskclip"}: [1, 5, 7, 16] each,
                  unit vectors. The last block is replaced by
                    naclip:    softmax(k k^T * scale + omega) v, omega a
                               Gaussian (std 5 patches, peak 1) of the grid
                               distance between patch tokens, zero on the
                               class token's row and column
                    clearclip: softmax(q q^T * scale) v
                    maskclip:  v
                  then out_proj, no residual, no MLP; the patch tokens go
                  through the post-LN and the projection, L2-normalised.
  sliding         {"image_rgb": a seeded 45 x 70 RGB uint8 image, HWC,
                  "height": 45, "width": 70, "short_side": 48,
                  "resized": [3, 48, 72] the image / 255 resized (bilinear,
                  antialiased, patch-rounded size) and normalised,
                  "features": [6, 9, 16] the naclip features of 32 x 32
                  windows (stride 16) averaged and re-normalised,
                  "grid": [6, 9]} (the image is the same in both)
  resize_down     {"short_side": 16, "resized": [3, 16, 24]} the same image
                  downscaled (the antialiased path)

With --full-size, writes instead (not checked in) OUT/hf_vit_b16/: a random
Hugging Face CLIPModel with a ViT-B/16 vision tower (width 768, 12 layers,
12 heads, image 224, patch 16, quick-GELU, projection 512) and hf_tiny's text
tower, with reference.json: image_embeds of [1, 3, 224, 224] native_pixels
and dense.naclip [1, 14, 21, 512] of [1, 3, 224, 336] dense_pixels.

The dense path is plain torch code (dense_last_block); the libraries give
only the standard layers. The script checks that its own embedding path
with the original last block reproduces the library's image embedding, and
that interpolating the position embeddings to the native grid is the
identity. scripts/bench_vlm_torch.py imports the dense and sliding code.

Needs torch, transformers, open_clip_torch and safetensors. Deterministic
(seeded).

    python3 tests/clip_vision_reference.py [OUT]
    python3 tests/clip_vision_reference.py --full-size OUT
"""

import json
import math
import os
import sys

import numpy as np
import torch
import torch.nn.functional as F

OPENAI_MEAN = (0.48145466, 0.4578275, 0.40821073)
OPENAI_STD = (0.26862954, 0.26130258, 0.27577711)
VARIANTS = ("naclip", "clearclip", "maskclip")
NACLIP_STD = 5.0


def out_dir():
    if len(sys.argv) > 1:
        return sys.argv[1]
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.join(here, "..", "clip", "tests", "fixtures", "vision")


def save_json(path, value, indent=1):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(value, f, ensure_ascii=False, indent=indent)
        f.write("\n")


def save_reference(path, value):
    """One top-level key a line, each value compact (the arrays are long)."""
    lines = [
        f" {json.dumps(k)}: {json.dumps(v, ensure_ascii=False, separators=(',', ':'))}"
        for k, v in value.items()
    ]
    with open(path, "w", encoding="utf-8") as f:
        f.write("{\n" + ",\n".join(lines) + "\n}\n")


def flat(t):
    return [round(float(x), 7) for x in t.detach().reshape(-1).tolist()]


def seeded_pixels(shape):
    """A normal tensor rounded to 3 decimals (short in JSON, exact in f32)."""
    return torch.round(torch.randn(shape) * 1000) / 1000


def perturb(model, scale=0.05):
    # Default init leaves biases and norms at 0 / 1: perturb every parameter
    # so that a misplaced bias or norm weight shows.
    with torch.no_grad():
        for p in model.parameters():
            p.add_(scale * torch.randn_like(p))


# ---------------------------------------------------------------------------
# The vision tower, as plain torch around the libraries' standard layers.


class Tower:
    """What the dense path needs of a CLIP ViT: the patch conv, class and
    position embeddings, pre-LN, the blocks but the last (as a function),
    the last block's weights, the original last block, post-LN and the
    projection matrix [width, D]."""

    def __init__(self, **kw):
        self.__dict__.update(kw)


def hf_tower(model):
    """model: a transformers CLIPModel or CLIPVisionModelWithProjection."""
    vm = model.vision_model
    emb = vm.embeddings
    layers = vm.encoder.layers
    last = layers[-1]
    attn = last.self_attn

    def blocks(x):
        for layer in layers[:-1]:
            x = layer(x, None)
            if isinstance(x, tuple):
                x = x[0]
        return x

    def last_block(x):
        x = last(x, None)
        return x[0] if isinstance(x, tuple) else x

    return Tower(
        patch=emb.patch_size,
        image_size=emb.image_size,
        conv=emb.patch_embedding,
        class_embedding=emb.class_embedding,
        positions=emb.position_embedding.weight,
        ln_pre=vm.pre_layrnorm,
        blocks=blocks,
        last_block=last_block,
        ln_1=last.layer_norm1,
        heads=attn.num_heads,
        wq=attn.q_proj.weight, bq=attn.q_proj.bias,
        wk=attn.k_proj.weight, bk=attn.k_proj.bias,
        wv=attn.v_proj.weight, bv=attn.v_proj.bias,
        wo=attn.out_proj.weight, bo=attn.out_proj.bias,
        ln_post=vm.post_layernorm,
        proj=model.visual_projection.weight.t(),
        library_embeddings=lambda px: emb(px, interpolate_pos_encoding=True),
    )


def openclip_tower(model):
    """model: an open_clip CLIP with a standard VisionTransformer."""
    v = model.visual
    t = v.transformer
    last = t.resblocks[-1]
    attn = last.attn
    width = v.conv1.out_channels
    wq, wk, wv = attn.in_proj_weight.split(width, dim=0)
    bq, bk, bv = attn.in_proj_bias.split(width, dim=0)

    def run(block_list, x):
        if not t.batch_first:
            x = x.transpose(0, 1)
        for r in block_list:
            x = r(x)
        if not t.batch_first:
            x = x.transpose(0, 1)
        return x

    return Tower(
        patch=v.conv1.kernel_size[0],
        image_size=v.image_size[0] if isinstance(v.image_size, tuple) else v.image_size,
        conv=v.conv1,
        class_embedding=v.class_embedding,
        positions=v.positional_embedding,
        ln_pre=v.ln_pre,
        blocks=lambda x: run(t.resblocks[:-1], x),
        last_block=lambda x: run([last], x),
        ln_1=last.ln_1,
        heads=attn.num_heads,
        wq=wq, bq=bq, wk=wk, bk=bk, wv=wv, bv=bv,
        wo=attn.out_proj.weight, bo=attn.out_proj.bias,
        ln_post=v.ln_post,
        proj=v.proj,
        library_embeddings=None,
    )


def interpolate_positions(positions, gh, gw):
    """[1 + g0*g0, width] -> [1 + gh*gw, width]: the class position as is,
    the patch positions resized bicubically (align_corners=False)."""
    n, width = positions.shape
    g0 = int(round(math.sqrt(n - 1)))
    assert g0 * g0 == n - 1
    grid = positions[1:].reshape(g0, g0, width).permute(2, 0, 1).unsqueeze(0)
    grid = F.interpolate(grid, size=(gh, gw), mode="bicubic", align_corners=False)
    patches = grid[0].permute(1, 2, 0).reshape(gh * gw, width)
    return torch.cat([positions[:1], patches], dim=0)


def embed_tokens(tower, pixels):
    """Pixels [B, 3, H, W] -> class + patch tokens with positions (pre-LN)."""
    b, _, h, w = pixels.shape
    p = tower.patch
    assert h % p == 0 and w % p == 0, (h, w, p)
    gh, gw = h // p, w // p
    x = tower.conv(pixels).flatten(2).transpose(1, 2)
    cls = tower.class_embedding.reshape(1, 1, -1).expand(b, 1, -1)
    x = torch.cat([cls, x], dim=1)
    return x + interpolate_positions(tower.positions, gh, gw).unsqueeze(0)


def embed(tower, pixels):
    """Pixels [B, 3, H, W] -> the last block's input [B, 1 + N, width]."""
    return tower.blocks(tower.ln_pre(embed_tokens(tower, pixels)))


def naclip_omega(gh, gw, std=NACLIP_STD):
    """[1 + N, 1 + N]: exp(-d^2 / (2 std^2)) between patch tokens, d their
    grid distance; zero on the class token's row and column."""
    i = torch.arange(gh).repeat_interleave(gw).float()
    j = torch.arange(gw).repeat(gh).float()
    d2 = (i[:, None] - i[None, :]) ** 2 + (j[:, None] - j[None, :]) ** 2
    n = gh * gw
    omega = torch.zeros(1 + n, 1 + n)
    omega[1:, 1:] = torch.exp(-d2 / (2 * std * std))
    return omega


def dense_last_block(variant, x, ln_1, wq, bq, wk, bk, wv, bv, wo, bo, heads, grid):
    """The modified last block: x [B, 1 + N, width] -> [B, 1 + N, width]
    (no residual, no MLP). grid = (gh, gw) of the N patch tokens."""
    b, t, width = x.shape
    hd = width // heads
    scale = hd ** -0.5
    h = ln_1(x)

    def split(y):
        return y.reshape(b, t, heads, hd).transpose(1, 2)  # [B, heads, T, hd]

    v = h @ wv.t() + bv
    if variant == "maskclip":
        out = v
    else:
        if variant == "naclip":
            k = split(h @ wk.t() + bk)
            logits = k @ k.transpose(-1, -2) * scale + naclip_omega(*grid).to(x.dtype)
        elif variant == "clearclip":
            q = split(h @ wq.t() + bq)
            logits = q @ q.transpose(-1, -2) * scale
        else:
            raise ValueError(f"unknown dense variant {variant!r}")
        attn = logits.softmax(dim=-1)
        out = (attn @ split(v)).transpose(1, 2).reshape(b, t, width)
    return out @ wo.t() + bo


def dense_features(tower, variant, pixels):
    """Pixels [B, 3, H, W] -> unit vectors [B, H/p, W/p, D]."""
    b, _, h, w = pixels.shape
    gh, gw = h // tower.patch, w // tower.patch
    x = embed(tower, pixels)
    y = dense_last_block(
        variant, x, tower.ln_1,
        tower.wq, tower.bq, tower.wk, tower.bk, tower.wv, tower.bv,
        tower.wo, tower.bo, tower.heads, (gh, gw),
    )
    y = tower.ln_post(y[:, 1:]) @ tower.proj
    y = y / y.norm(dim=-1, keepdim=True)
    return y.reshape(b, gh, gw, -1)


def class_embedding_path(tower, pixels):
    """Our embedding path with the original last block: the class token
    through post-LN and the projection (the standard image embedding)."""
    x = tower.last_block(embed(tower, pixels))
    return tower.ln_post(x[:, 0]) @ tower.proj


# ---------------------------------------------------------------------------
# Sliding windows over an RGB image.


def round_to_patch(v, p):
    # Half away from zero (as Rust's f32::round), not Python's banker's round.
    return max(p, int(math.floor(v / p + 0.5)) * p)


def resize_normalise(image, short_side, patch, mean=OPENAI_MEAN, std=OPENAI_STD):
    """image: HWC uint8 (numpy or tensor) -> [1, 3, H', W'] normalised, the
    short side scaled to short_side and both sides rounded to the patch."""
    image = torch.as_tensor(np.asarray(image))
    h, w = image.shape[0], image.shape[1]
    x = image.permute(2, 0, 1).unsqueeze(0).to(torch.float32) / 255
    s = short_side / min(h, w)
    size = (round_to_patch(h * s, patch), round_to_patch(w * s, patch))
    x = F.interpolate(x, size=size, mode="bilinear", align_corners=False, antialias=True)
    m = torch.tensor(mean, dtype=torch.float32).reshape(1, 3, 1, 1)
    sd = torch.tensor(std, dtype=torch.float32).reshape(1, 3, 1, 1)
    return (x - m) / sd


def window_origins(length, crop, stride):
    assert length >= crop, (length, crop)
    if length == crop:
        return [0]
    n = math.ceil((length - crop) / stride) + 1
    return [min(k * stride, length - crop) for k in range(n)]


def windows(h, w, crop, patch):
    """Every (row, col) window origin, rows outer."""
    stride = patch * max(1, (crop // patch) // 2)
    return [(y, x) for y in window_origins(h, crop, stride) for x in window_origins(w, crop, stride)]


def sliding_dense(tower, variant, pixels):
    """pixels [1, 3, H', W'] (normalised) -> unit vectors [H'/p, W'/p, D]:
    every window's dense features (one batch), averaged per cell."""
    c, p = tower.image_size, tower.patch
    _, _, h, w = pixels.shape
    origins = windows(h, w, c, p)
    batch = torch.cat([pixels[:, :, y : y + c, x : x + c] for y, x in origins], dim=0)
    feats = dense_features(tower, variant, batch)  # [n, c/p, c/p, D]
    gh, gw, g = h // p, w // p, c // p
    acc = torch.zeros(gh, gw, feats.shape[-1], dtype=feats.dtype)
    count = torch.zeros(gh, gw, 1, dtype=feats.dtype)
    for (y, x), f in zip(origins, feats):
        acc[y // p : y // p + g, x // p : x // p + g] += f
        count[y // p : y // p + g, x // p : x // p + g] += 1
    acc = acc / count
    return acc / acc.norm(dim=-1, keepdim=True)


# ---------------------------------------------------------------------------
# Checks and the reference file.


def check_tower(tower, native_pixels, image_embeds, name, other_pixels=None):
    g0 = tower.image_size // tower.patch
    same = interpolate_positions(tower.positions, g0, g0)
    err = (same - tower.positions).abs().max().item()
    assert err <= 1e-6, f"{name}: interpolating to the native grid changes positions by {err}"
    ours = class_embedding_path(tower, native_pixels)
    err = (ours - image_embeds).abs().max().item()
    tol = 1e-5 * max(1.0, image_embeds.abs().max().item())
    assert err <= tol, f"{name}: own embedding path differs from the image embedding by {err}"
    if other_pixels is not None and tower.library_embeddings is not None:
        # Transformers' own position interpolation, at a non-square size.
        err = (embed_tokens(tower, other_pixels) - tower.library_embeddings(other_pixels)).abs().max().item()
        assert err <= 1e-5, f"{name}: interpolated embeddings differ from the library's by {err}"


def sliding_image():
    """The seeded 45 x 70 RGB test image, the same for every model."""
    g = torch.Generator().manual_seed(7)
    return torch.randint(0, 256, (45, 70, 3), dtype=torch.uint8, generator=g)


def sliding_reference(tower):
    image = sliding_image()
    pixels = resize_normalise(image, 48, tower.patch)
    assert pixels.shape == (1, 3, 48, 72), pixels.shape
    feats = sliding_dense(tower, "naclip", pixels)
    assert feats.shape[:2] == (6, 9), feats.shape
    down = resize_normalise(image, 16, tower.patch)
    assert down.shape == (1, 3, 16, 24), down.shape
    sliding = {
        "image_rgb": image.reshape(-1).tolist(),
        "height": 45,
        "width": 70,
        "short_side": 48,
        "resized": flat(pixels),
        "features": flat(feats),
        "grid": [6, 9],
    }
    return sliding, {"short_side": 16, "resized": flat(down)}


def tiny_reference(tower, image_embeds_fn, generator_text, seed):
    torch.manual_seed(seed)
    native = seeded_pixels((2, 3, 32, 32))
    dense_px = seeded_pixels((1, 3, 40, 56))
    with torch.no_grad():
        image_embeds = image_embeds_fn(native)
        check_tower(tower, native, image_embeds, generator_text, dense_px)
        dense = {v: dense_features(tower, v, dense_px) for v in VARIANTS}
        for v, d in dense.items():
            assert d.shape == (1, 5, 7, 16), (v, d.shape)
        sliding, down = sliding_reference(tower)
    return {
        "generator": generator_text,
        "native_pixels": flat(native),
        "image_embeds": flat(image_embeds),
        "dense_pixels": flat(dense_px),
        "dense": {v: flat(d) for v, d in dense.items()},
        "sliding": sliding,
        "resize_down": down,
    }


def hf_image_embeds(model):
    def f(pixels):
        out = model.get_image_features(pixel_values=pixels)
        return out if torch.is_tensor(out) else out.pooler_output

    return f


from clip_reference import HF_TINY_TEXT as HF_TEXT  # noqa: E402

# CLIP ViT-B/16's vision tower (the full-size reference and the PyTorch
# benchmark).
VIT_B16 = dict(
    hidden_size=768,
    intermediate_size=3072,
    projection_dim=512,
    num_hidden_layers=12,
    num_attention_heads=12,
    image_size=224,
    patch_size=16,
    hidden_act="quick_gelu",
    layer_norm_eps=1e-5,
)


def preprocessor_config(size):
    return {
        "crop_size": {"height": size, "width": size},
        "do_center_crop": True,
        "do_convert_rgb": True,
        "do_normalize": True,
        "do_rescale": True,
        "do_resize": True,
        "image_mean": list(OPENAI_MEAN),
        "image_processor_type": "CLIPImageProcessor",
        "image_std": list(OPENAI_STD),
        "resample": 3,
        "rescale_factor": 1 / 255,
        "size": {"shortest_edge": size},
    }


def quiet_transformers():
    from transformers.utils import logging

    logging.disable_progress_bar()


def hf_model(out):
    import transformers
    from transformers import CLIPConfig, CLIPModel

    quiet_transformers()
    torch.manual_seed(10)
    vision = dict(
        hidden_size=32,
        intermediate_size=64,
        projection_dim=16,
        num_hidden_layers=2,
        num_attention_heads=4,
        image_size=32,
        patch_size=8,
        hidden_act="quick_gelu",
        layer_norm_eps=1e-5,
    )
    config = CLIPConfig(text_config=HF_TEXT, vision_config=vision, projection_dim=16)
    model = CLIPModel(config).eval()
    perturb(model)
    d = os.path.join(out, "hf_tiny")
    os.makedirs(d, exist_ok=True)
    model.save_pretrained(d, safe_serialization=True)
    save_json(os.path.join(d, "preprocessor_config.json"), preprocessor_config(32))
    ref = tiny_reference(
        hf_tower(model),
        hf_image_embeds(model),
        f"transformers {transformers.__version__}, torch {torch.__version__}",
        seed=11,
    )
    save_reference(os.path.join(d, "reference.json"), ref)


def openclip_model(out):
    import open_clip
    from open_clip.model import CLIP
    from safetensors.torch import save_file

    torch.manual_seed(20)
    text_cfg = dict(context_length=16, vocab_size=40, width=32, heads=4, layers=2)
    vision_cfg = dict(image_size=32, patch_size=8, width=32, layers=2, head_width=8)
    model = CLIP(embed_dim=16, vision_cfg=vision_cfg, text_cfg=text_cfg, quick_gelu=True).eval()
    perturb(model)
    state = {k: v.detach().to(torch.float32).contiguous() for k, v in model.state_dict().items()}
    d = os.path.join(out, "openclip_tiny")
    os.makedirs(d, exist_ok=True)
    save_file(state, os.path.join(d, "open_clip_model.safetensors"))
    save_json(
        os.path.join(d, "open_clip_config.json"),
        {
            "model_cfg": {
                "embed_dim": 16,
                "quick_gelu": True,
                "vision_cfg": vision_cfg,
                "text_cfg": text_cfg,
            },
            "preprocess_cfg": {"mean": list(OPENAI_MEAN), "std": list(OPENAI_STD)},
        },
    )
    ref = tiny_reference(
        openclip_tower(model),
        model.encode_image,
        f"open_clip_torch {open_clip.__version__}, torch {torch.__version__}",
        seed=21,
    )
    save_reference(os.path.join(d, "reference.json"), ref)


def full_size(out):
    import transformers
    from transformers import CLIPConfig, CLIPModel

    quiet_transformers()
    torch.manual_seed(30)
    text = dict(HF_TEXT, projection_dim=512)
    vision = VIT_B16
    model = CLIPModel(CLIPConfig(text_config=text, vision_config=vision, projection_dim=512)).eval()
    perturb(model)
    d = os.path.join(out, "hf_vit_b16")
    os.makedirs(d, exist_ok=True)
    model.save_pretrained(d, safe_serialization=True)
    save_json(os.path.join(d, "preprocessor_config.json"), preprocessor_config(224))
    tower = hf_tower(model)
    torch.manual_seed(31)
    native = seeded_pixels((1, 3, 224, 224))
    dense_px = seeded_pixels((1, 3, 224, 336))
    with torch.no_grad():
        image_embeds = hf_image_embeds(model)(native)
        check_tower(tower, native, image_embeds, "hf_vit_b16", dense_px)
        dense = dense_features(tower, "naclip", dense_px)
    assert dense.shape == (1, 14, 21, 512), dense.shape
    save_reference(
        os.path.join(d, "reference.json"),
        {
            "generator": f"transformers {transformers.__version__}, torch {torch.__version__}",
            "native_pixels": flat(native),
            "image_embeds": flat(image_embeds),
            "dense_pixels": flat(dense_px),
            "dense": {"naclip": flat(dense)},
        },
    )
    print(f"wrote {os.path.abspath(d)}")


def main():
    torch.set_grad_enabled(False)
    if len(sys.argv) > 2 and sys.argv[1] == "--full-size":
        full_size(sys.argv[2])
        return
    out = out_dir()
    os.makedirs(out, exist_ok=True)
    hf_model(out)
    openclip_model(out)
    print(f"wrote {os.path.abspath(out)}")


if __name__ == "__main__":
    main()
