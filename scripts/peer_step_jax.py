#!/usr/bin/env python3
"""The plain (per-sample feature) OpenNeRF training step in JAX on the CPU:
the peer that `bench --peer PYTHON` times against in the same run.

Written after model/src/{mip,field,nerf,composite,sampling,loss}.rs and
train/src/step.rs, with the sizes of bench/src/bin/bench: rays, coarse and
fine samples (the fine posts resampled from the blurred coarse weights by
inverse-CDF sampling, as model/src/sampling.rs does), Mip-NeRF IPE of the
conical-frustum Gaussians (degrees 0..16), the 8 x 256 trunk with the encoding
re-injected at the skip layer, density softplus(raw - 1), the view-dependent
colour branch, the feature head (2 hidden ReLU layers, then the output layer)
on every fine sample of the detached trunk, composited with detached weights
(weighted mean), the losses of the bench step (fine colour MSE + 0.1 coarse
colour MSE + open-set cosine; the bench batch has no depth), the L1 norm of
the gradients and the finite-loss guard, and Adam (Burn's defaults: betas
0.9 / 0.999, epsilon 1e-5, lr 1e-4). The whole step (forward, grad, Adam) is
one `jax.jit`.

    python3 scripts/peer_step_jax.py [--rays 1024 --samples 32 --width 256
        --depth 8 --head-width 256 --feature-dim 768 --steps 2 --threads N]

Prints one JSON line on stdout (everything else on stderr):
{"impl": "jax", "jax": ..., "threads": ..., "seconds_per_step": ...,
 "per_step": [...], "rays_per_s": ..., "gflop_per_step": ...,
 "gflop_per_s": ..., "matmul_gflop_per_s": ..., "peak_mb": ...}
GFLOP are counted as bench's `Size::step_flops` counts the per-sample path.
"""
import argparse
import json
import os
import resource
import sys
import time


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rays", type=int, default=1024)
    p.add_argument("--samples", type=int, default=32, help="samples per ray at each level")
    p.add_argument("--width", type=int, default=256, help="trunk width")
    p.add_argument("--depth", type=int, default=8, help="trunk layers")
    p.add_argument("--skip", type=int, default=None,
                   help="skip layer [default: 4 when depth > 4, else depth / 2, as bench]")
    p.add_argument("--head-width", type=int, default=256)
    p.add_argument("--feature-dim", type=int, default=768)
    p.add_argument("--min-deg", type=int, default=0)
    p.add_argument("--max-deg", type=int, default=16)
    p.add_argument("--viewdir-deg", type=int, default=4)
    p.add_argument("--steps", type=int, default=2, help="timed steps after one warm-up")
    p.add_argument("--threads", type=int, default=None,
                   help="CPU threads [default: the cores this process may use]")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    if a.skip is None:
        a.skip = 4 if a.depth > 4 else a.depth // 2
    return a


ARGS = parse_args()
AVAILABLE = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
THREADS = ARGS.threads or (len(AVAILABLE) if AVAILABLE else os.cpu_count() or 1)
# Thread settings must be in place before jax is imported.
os.environ["JAX_PLATFORMS"] = "cpu"
os.environ["XLA_FLAGS"] = (
    os.environ.get("XLA_FLAGS", "")
    + f" --xla_cpu_multi_thread_eigen={'true' if THREADS > 1 else 'false'}"
    + f" intra_op_parallelism_threads={THREADS}"
).strip()
if AVAILABLE and ARGS.threads and ARGS.threads < len(AVAILABLE):
    os.sched_setaffinity(0, AVAILABLE[: ARGS.threads])

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

BETA1, BETA2, ADAM_EPS, LR = 0.9, 0.999, 1e-5, 1e-4
COARSE_WEIGHT, LAMBDA_OPEN = 0.1, 1.0
RESAMPLE_PADDING = 0.01
FEATURE_ACC_EPS, COSINE_EPS = 1e-6, 1e-6


def log(*a):
    print(*a, file=sys.stderr, flush=True)


# ---------------------------------------------------------------- parameters
def linear_init(key, d_in, d_out, fan_in=None, bias=True):
    """Burn's default Linear init: uniform +-1/sqrt(fan_in) for weight and bias."""
    bound = 1.0 / max(fan_in or d_in, 1) ** 0.5
    kw, kb = jax.random.split(key)
    p = {"w": jax.random.uniform(kw, (d_in, d_out), jnp.float32, -bound, bound)}
    if bias:
        p["b"] = jax.random.uniform(kb, (d_out,), jnp.float32, -bound, bound)
    return p


def linear(p, x):
    y = x @ p["w"]
    return y + p["b"] if "b" in p else y


def init_params(key, a):
    inp = 6 * (a.max_deg - a.min_deg)
    view = 3 + 6 * a.viewdir_deg
    w, half = a.width, max(a.width // 2, 1)
    keys = iter(jax.random.split(key, 2 * a.depth + 16))
    trunk, skip = [], None
    for i in range(a.depth):
        if i > 0 and i == a.skip:
            trunk.append(linear_init(next(keys), w, w, fan_in=w + inp))
            skip = linear_init(next(keys), inp, w, fan_in=w + inp, bias=False)
        else:
            trunk.append(linear_init(next(keys), inp if i == 0 else w, w))
    mlp = {
        "trunk": trunk,
        "density": linear_init(next(keys), w, 1),
        "bottleneck": linear_init(next(keys), w, w),
        "view_bottleneck": linear_init(next(keys), w, half, fan_in=w + view),
        "view_dir": linear_init(next(keys), view, half, fan_in=w + view, bias=False),
        "rgb": linear_init(next(keys), half, 3),
    }
    if skip is not None:
        mlp["skip"] = skip
    head = {
        "hidden": [linear_init(next(keys), w, a.head_width),
                   linear_init(next(keys), a.head_width, a.head_width)],
        "output": linear_init(next(keys), a.head_width, a.feature_dim),
    }
    return {"mlp": mlp, "head": head}


# ------------------------------------------------------------------ encoding
def frequency_matrix(min_deg, max_deg, squared):
    """[3, 6 L]: sin block then cos block, each degree-major (as mip.rs)."""
    levels = max_deg - min_deg
    cols = []
    for _half in range(2):
        for l in range(levels):
            s = 2.0 ** (min_deg + l)
            s = s * s if squared else s
            for k in range(3):
                c = [0.0, 0.0, 0.0]
                c[k] = s
                cols.append(c)
    return jnp.array(cols, jnp.float32).T


def phase_row(levels):
    return jnp.concatenate([jnp.zeros(3 * levels), jnp.full(3 * levels, jnp.pi / 2)])[None, :]


def integrated_pos_enc(mean, cov, min_deg, max_deg):
    y = mean @ frequency_matrix(min_deg, max_deg, False) + phase_row(max_deg - min_deg)
    y_var = cov @ frequency_matrix(min_deg, max_deg, True)
    return jnp.exp(-0.5 * y_var) * jnp.sin(y)


def pos_enc(x, min_deg, max_deg):
    enc = jnp.sin(x @ frequency_matrix(min_deg, max_deg, False) + phase_row(max_deg - min_deg))
    return jnp.concatenate([x, enc], axis=-1)


def cast_rays(t_vals, origins, directions, radii):
    t0, t1 = t_vals[:, :-1], t_vals[:, 1:]
    mu, hw = 0.5 * (t0 + t1), 0.5 * (t1 - t0)
    mu2, hw2 = mu * mu, hw * hw
    hw4 = hw2 * hw2
    denom = jnp.maximum(3.0 * mu2 + hw2, 1e-20)
    t_mean = mu + 2.0 * mu * hw2 / denom
    t_var = hw2 / 3.0 - (4.0 / 15.0) * hw4 * (12.0 * mu2 - hw2) / (denom * denom)
    r_var = (mu2 / 4.0 + (5.0 / 12.0) * hw2 - (4.0 / 15.0) * hw4 / denom) * radii * radii
    d = directions[:, None, :]
    d2 = d * d
    null_outer = 1.0 - d2 / jnp.maximum(d2.sum(-1, keepdims=True), 1e-10)
    mean = d * t_mean[..., None] + origins[:, None, :]
    cov = d2 * t_var[..., None] + null_outer * r_var[..., None]
    return mean, cov


# ------------------------------------------------------------------ sampling
def stratified_t_vals(key, near, far, samples):
    posts = samples + 1
    t = near + (far - near) * jnp.linspace(0.0, 1.0, posts)[None, :]
    mids = 0.5 * (t[:, :-1] + t[:, 1:])
    upper = jnp.concatenate([mids, t[:, -1:]], 1)
    lower = jnp.concatenate([t[:, :1], mids], 1)
    u = jax.random.uniform(key, t.shape)
    return jax.lax.stop_gradient(lower + (upper - lower) * u)


def blur_weights(w, padding):
    padded = jnp.concatenate([w[:, :1], w, w[:, -1:]], 1)
    maxes = jnp.maximum(padded[:, :-1], padded[:, 1:])
    return 0.5 * (maxes[:, :-1] + maxes[:, 1:]) + padding


def sample_pdf(key, bins, weights, num_posts):
    """Inverse-CDF sampling with the [rays, s + 1, posts] mask of sampling.rs."""
    rays, s = weights.shape
    eps = 1e-5
    wsum = weights.sum(1, keepdims=True)
    pad = jnp.maximum(eps - wsum, 0.0)
    pdf = (weights + pad / s) / (wsum + pad)
    cdf = jnp.concatenate(
        [jnp.zeros((rays, 1)), jnp.minimum(jnp.cumsum(pdf[:, :-1], 1), 1.0), jnp.ones((rays, 1))], 1)
    step = 1.0 / num_posts
    base = jnp.linspace(0.0, step * (max(num_posts, 2) - 1), num_posts)[None, :]
    u = jnp.minimum(base + jax.random.uniform(key, (rays, num_posts), maxval=step - 1.2e-7), 1.0 - eps)
    mask = u[:, None, :] >= cdf[:, :, None]

    def find(x):
        full = x[:, :, None]
        x0 = jnp.where(mask, full, x[:, :1, None]).max(1)
        x1 = jnp.where(mask, x[:, -1:, None], full).min(1)
        return x0, x1

    b0, b1 = find(bins)
    c0, c1 = find(cdf)
    denom = c1 - c0
    t = jnp.clip(jnp.where(denom <= 0.0, 0.0, (u - c0) / jnp.maximum(denom, 1e-20)), 0.0, 1.0)
    return jax.lax.stop_gradient(b0 + t * (b1 - b0))


def resample_t_vals(key, t_vals, weights):
    blurred = blur_weights(jax.lax.stop_gradient(weights), RESAMPLE_PADDING)
    return sample_pdf(key, jax.lax.stop_gradient(t_vals), blurred, t_vals.shape[1])


# ----------------------------------------------------------------- the field
def mlp_forward(p, ipe, view_enc, samples, skip):
    h = ipe
    for i, layer in enumerate(p["trunk"]):
        z = linear(layer, h)
        if "skip" in p and i == skip:
            z = z + linear(p["skip"], ipe)
        h = jax.nn.relu(z)
    density = jax.nn.softplus(linear(p["density"], h) - 1.0)
    b = linear(p["view_bottleneck"], linear(p["bottleneck"], h))
    n, half = b.shape
    rays = n // samples
    v = linear(p["view_dir"], view_enc)[:, None, :]
    c = jax.nn.relu(b.reshape(rays, samples, half) + v).reshape(n, half)
    rgb = jax.nn.sigmoid(linear(p["rgb"], c)) * (1.0 + 2.0 * 0.001) - 0.001
    return h, density, rgb


def head_forward(p, trunk):
    h = jax.lax.stop_gradient(trunk)
    for layer in p["hidden"]:
        h = jax.nn.relu(linear(layer, h))
    return linear(p["output"], h)


def compute_weights(density, t_vals, dir_norm):
    delta = (t_vals[:, 1:] - t_vals[:, :-1]) * dir_norm
    tau = density * delta
    alpha = 1.0 - jnp.exp(-tau)
    exclusive = jnp.concatenate([jnp.zeros_like(tau[:, :1]), jnp.cumsum(tau[:, :-1], 1)], 1)
    return alpha * jnp.exp(-exclusive)


def render_level(params, rays, t_vals, view_enc, dir_norm, with_feature, a):
    origins, directions, radii = rays["origins"], rays["directions"], rays["radii"]
    n, s = t_vals.shape[0], t_vals.shape[1] - 1
    mean, cov = cast_rays(t_vals, origins, directions, radii)
    ipe = integrated_pos_enc(mean.reshape(-1, 3), cov.reshape(-1, 3), a.min_deg, a.max_deg)
    trunk, density, rgb = mlp_forward(params["mlp"], ipe, view_enc, s, a.skip)
    weights = compute_weights(density.reshape(n, s), t_vals, dir_norm)
    acc = weights.sum(1, keepdims=True)
    t_mid = 0.5 * (t_vals[:, :-1] + t_vals[:, 1:])
    depth = (weights * t_mid).sum(1, keepdims=True) / jnp.maximum(acc, 1e-10)
    color = jnp.einsum("ns,nsc->nc", weights, rgb.reshape(n, s, 3))
    feature = None
    if with_feature:
        f = head_forward(params["head"], trunk).reshape(n, s, -1)
        w = jax.lax.stop_gradient(weights)
        feature = jnp.einsum("ns,nsc->nc", w, f) / jnp.maximum(
            w.sum(1, keepdims=True), FEATURE_ACC_EPS)
    return {"rgb": color, "depth": depth, "acc": acc, "weights": weights,
            "t_vals": t_vals, "feature": feature}


def render(params, rays, key, a):
    k_coarse, k_fine = jax.random.split(key)
    directions = rays["directions"]
    dir_norm = jnp.sqrt((directions ** 2).sum(1, keepdims=True))
    view_enc = pos_enc(directions / jnp.maximum(dir_norm, 1e-20), 0, a.viewdir_deg)
    t_coarse = stratified_t_vals(k_coarse, rays["near"], rays["far"], a.samples)
    # Coarse features are off (OpenNerfConfig::coarse_features = false).
    coarse = render_level(params, rays, t_coarse, view_enc, dir_norm, False, a)
    t_fine = resample_t_vals(k_fine, coarse["t_vals"], coarse["weights"])
    fine = render_level(params, rays, t_fine, view_enc, dir_norm, True, a)
    return coarse, fine


def open_set_cosine(pred, target, mask):
    eps2 = COSINE_EPS * COSINE_EPS
    dot = (pred * target).sum(1, keepdims=True)
    p2 = (pred * pred).sum(1, keepdims=True)
    t2 = (target * target).sum(1, keepdims=True)
    valid = (t2 > eps2) & (mask > 0.5)
    count = jnp.maximum(valid.sum(), 1.0)
    cos = dot / (jnp.sqrt(jnp.maximum(p2, eps2)) * jnp.sqrt(jnp.maximum(t2, eps2)))
    return jnp.where(valid, 1.0 - cos, 0.0).sum() / count


def loss_fn(params, batch, key, a):
    coarse, fine = render(params, batch["rays"], key, a)
    rgb = ((fine["rgb"] - batch["rgb"]) ** 2).mean()
    coarse_rgb = ((coarse["rgb"] - batch["rgb"]) ** 2).mean()
    open_ = open_set_cosine(fine["feature"], batch["feature"], batch["mask"])
    total = rgb + COARSE_WEIGHT * coarse_rgb + LAMBDA_OPEN * open_
    return total, (rgb, open_)


def make_step(a):
    def step(params, opt, batch, key):
        (total, (rgb, open_)), grads = jax.value_and_grad(loss_fn, has_aux=True)(
            params, batch, key, a)
        leaves = jax.tree_util.tree_leaves(grads)
        grad_l1 = sum(jnp.abs(g).sum() for g in leaves)
        ok = jnp.isfinite(total) & jnp.isfinite(rgb) & jnp.isfinite(open_) & jnp.isfinite(grad_l1)
        t = opt["t"] + 1
        m = jax.tree_util.tree_map(lambda m, g: BETA1 * m + (1 - BETA1) * g, opt["m"], grads)
        v = jax.tree_util.tree_map(lambda v, g: BETA2 * v + (1 - BETA2) * g * g, opt["v"], grads)
        c1, c2 = 1 - BETA1 ** t, 1 - BETA2 ** t
        new = jax.tree_util.tree_map(
            lambda p, m, v: p - LR * (m / c1) / (jnp.sqrt(v / c2) + ADAM_EPS), params, m, v)
        keep = lambda x, y: jnp.where(ok, x, y)  # noqa: E731 (the finite guard)
        params = jax.tree_util.tree_map(keep, new, params)
        opt = {"t": jnp.where(ok, t, opt["t"]),
               "m": jax.tree_util.tree_map(keep, m, opt["m"]),
               "v": jax.tree_util.tree_map(keep, v, opt["v"])}
        return params, opt, jnp.stack([total, rgb, open_, grad_l1])

    return jax.jit(step, donate_argnums=(0, 1))


# ----------------------------------------------------------------- the batch
def bench_rays(n, seed):
    """The rays of bench's `rays(n, seed)` (same LCG, same values)."""
    mask = (1 << 64) - 1
    mul, inc = 6364136223846793005, 1442695040888963407
    state = (seed * mul + inc) & mask

    def nxt():
        nonlocal state
        state = (state * mul + inc) & mask
        return (state >> 33) / float(1 << 31)

    o, d = [], []
    for _ in range(n):
        ox, oy = nxt() * 2.0 - 1.0, nxt() * 2.0 - 1.0
        dx, dy = nxt() - 0.5, nxt() - 0.5
        o.append([ox, oy, -2.5])
        d.append([dx, dy, 1.0])
    return {
        "origins": jnp.array(o, jnp.float32),
        "directions": jnp.array(d, jnp.float32),
        "radii": jnp.full((n, 1), 0.003, jnp.float32),
        "near": jnp.full((n, 1), 0.2, jnp.float32),
        "far": jnp.full((n, 1), 4.5, jnp.float32),
    }


def make_batch(key, a):
    k_rgb, k_feat = jax.random.split(key)
    f = jax.random.normal(k_feat, (a.rays, a.feature_dim), jnp.float32)
    return {
        "rays": bench_rays(a.rays, 1),
        "rgb": jax.random.uniform(k_rgb, (a.rays, 3), jnp.float32),
        "feature": f / jnp.linalg.norm(f, axis=1, keepdims=True),
        "mask": jnp.ones((a.rays, 1), jnp.float32),
    }


# ------------------------------------------------------------------- counting
def step_flops(a):
    """bench's `Size::step_flops` for FeatureMode::PerSample."""
    w, s, n = float(a.width), float(a.samples), float(a.rays)
    inp = 6.0 * (a.max_deg - a.min_deg)
    view = 3.0 + 6.0 * a.viewdir_deg
    per_sample = inp * w + (a.depth - 1.0) * w * w
    if 0 < a.skip < a.depth:
        per_sample += inp * w
    per_sample += w + w * w + w * (w / 2.0) + (w / 2.0) * 3.0
    per_ray_view = view * (w / 2.0)
    hw = float(a.head_width)
    hidden = w * hw + hw * hw
    head = s * n * (hidden + hw * a.feature_dim)
    return 3.0 * 2.0 * (2.0 * (n * s * per_sample + n * per_ray_view) + head)


def matmul_ceiling(w):
    """GFLOP/s of a [4096, w] x [w, w] product loop (as bench/src/bin/bench)."""
    ka, kb = jax.random.split(jax.random.PRNGKey(7))
    a = jax.random.uniform(ka, (4096, w), jnp.float32)
    b = jax.random.uniform(kb, (w, w), jnp.float32)
    f = jax.jit(lambda a, b: (a @ b).sum())
    f(a, b).block_until_ready()
    reps = 20
    start = time.perf_counter()
    acc = jnp.zeros(())
    for _ in range(reps):
        acc = acc + f(a, b)
    acc.block_until_ready()
    secs = time.perf_counter() - start
    return reps * 2.0 * 4096.0 * w * w / secs / 1e9


def main():
    a = ARGS
    log(f"jax {jax.__version__} on {jax.devices()[0].platform}, {THREADS} threads "
        f"(XLA_FLAGS={os.environ['XLA_FLAGS']!r})")
    log(f"step: {a.rays} rays x {a.samples}+{a.samples} samples, trunk {a.depth} x {a.width} "
        f"(skip {a.skip}), head 2 x {a.head_width} -> {a.feature_dim}, Adam")
    key = jax.random.PRNGKey(a.seed)
    k_init, k_batch, k_step = jax.random.split(key, 3)
    params = init_params(k_init, a)
    zeros = lambda p: jax.tree_util.tree_map(jnp.zeros_like, p)  # noqa: E731
    opt = {"t": jnp.zeros((), jnp.float32), "m": zeros(params), "v": zeros(params)}
    batch = make_batch(k_batch, a)
    step = make_step(a)
    times = []
    for i in range(a.steps + 1):
        k = jax.random.fold_in(k_step, i)
        start = time.perf_counter()
        params, opt, report = step(params, opt, batch, k)
        report = jax.device_get(report)  # the one host read per step, as step.rs
        secs = time.perf_counter() - start
        log(f"{'warm-up' if i == 0 else f'step {i}'}: {secs:.3f} s, loss {float(report[0]):.4f}, "
            f"rgb {float(report[1]):.4f}, open {float(report[2]):.4f}, grad_l1 {float(report[3]):.3g}")
        if i > 0:
            times.append(secs)
    mean = sum(times) / max(len(times), 1)
    flops = step_flops(a)
    ceiling = matmul_ceiling(a.width)
    out = {
        "impl": "jax",
        "jax": jax.__version__,
        "threads": THREADS,
        "seconds_per_step": mean,
        "per_step": times,
        "rays_per_s": a.rays / mean if mean > 0 else 0.0,
        "gflop_per_step": flops / 1e9,
        "gflop_per_s": flops / mean / 1e9 if mean > 0 else 0.0,
        "matmul_gflop_per_s": ceiling,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
