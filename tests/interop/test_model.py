"""docs/MODEL.md's recipe, in NumPy, against `actor predict`: the checkpoint's safetensors file
and config.toml, the preprocessing (image / 255 in channel-first order, speed / v0, d / d0, path
features' units) and the network ('same' 3x3 convolutions, ReLU, 2x2 average pooling, flatten,
concatenation, two ReLU layers, the Q layer) reproduce its Q values to 1e-5, for a trained gray
hybrid checkpoint and for an RGB hybrid checkpoint with path features. The arithmetic is
MODEL.md's PyTorch snippet's, step by step (PyTorch itself is not installed here)."""

import json
import subprocess
import tomllib

import numpy as np
import pytest
from PIL import Image
from safetensors.numpy import load_file

from conftest import ROOT, TINY_TOML, Learner, actor_train, binary

LANE_WIDTH = 3.5  # agent::features::LANE_WIDTH, metres


def predict(*args):
    done = subprocess.run([binary("actor"), "predict", *map(str, args), "--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def conv_same(x, w, b):
    """3x3 convolution, stride 1, zero padding 1 ('same'): x [C,H,W], w [F,C,3,3] -> [F,H,W]."""
    _, h, wd = x.shape
    p = np.pad(x, ((0, 0), (1, 1), (1, 1)))
    out = np.zeros((w.shape[0], h, wd))
    for i in range(3):
        for j in range(3):
            out += np.einsum("fc,chw->fhw", w[:, :, i, j], p[:, i:i + h, j:j + wd])
    return out + b[:, None, None]


def avg_pool2(x):
    """2x2 average pooling, stride 2, odd edges dropped (PyTorch's avg_pool2d(x, 2))."""
    f, h, w = x.shape
    return x[:, :h // 2 * 2, :w // 2 * 2].reshape(f, h // 2, 2, w // 2, 2).mean(axis=(2, 4))


def q_values(checkpoint_dir, frame_png, raw):
    cfg = tomllib.loads((checkpoint_dir / "config.toml").read_text())
    p = {k: v.astype(np.float64) for k, v in load_file(checkpoint_dir / "online.safetensors").items()}
    pixels = np.asarray(Image.open(frame_png), dtype=np.float64) / 255.0
    x = pixels[None, :, :] if pixels.ndim == 2 else pixels.transpose(2, 0, 1)  # [C,H,W]
    reward = cfg["env"]["reward"]
    scalars = [raw["speed_mps"] / (reward["v0_kmh"] / 3.6)]
    if cfg["env"]["variant"] == "hybrid":
        scalars.append(raw["d_m"] / reward["d0"])
        if cfg["agent"]["path_features"]:
            scalars += [raw["lateral_m"] / LANE_WIDTH, raw["near_heading_rad"], raw["far_heading_rad"]]
    for layer in ("conv1", "conv2", "conv3"):
        x = avg_pool2(np.maximum(conv_same(x, p[f"{layer}.weight"], p[f"{layer}.bias"]), 0.0))
    h = np.concatenate([x.reshape(-1), scalars])
    h = np.maximum(p["fc1.weight"] @ h + p["fc1.bias"], 0.0)
    h = np.maximum(p["fc2.weight"] @ h + p["fc2.bias"], 0.0)
    return np.array(scalars), p["q.weight"] @ h + p["q.bias"]


def check(checkpoint_dir, tmp_path, route, step):
    frame = tmp_path / f"{route}-{step}.png"
    got = predict("--checkpoint", checkpoint_dir, "--route", route, "--step", step, "--save-frame", frame)
    scalars, q = q_values(checkpoint_dir, frame, got["input"]["raw"])
    np.testing.assert_allclose(got["input"]["scalars"], scalars, rtol=0, atol=1e-6)
    np.testing.assert_allclose(got["q_values"], q, rtol=0, atol=1e-5)
    assert got["greedy_action"] == int(np.argmax(q))
    # The same observation given by hand (--frame and its scalars) gives the same Q values.
    raw = got["input"]["raw"]
    by_hand = ["--checkpoint", checkpoint_dir, "--frame", frame, "--speed", raw["speed_mps"]]
    if got["variant"] == "hybrid":
        by_hand += ["--d", raw["d_m"]]
        if got["path_features"]:
            by_hand += ["--path", f'{raw["lateral_m"]},{raw["near_heading_rad"]},{raw["far_heading_rad"]}']
    np.testing.assert_allclose(predict(*by_hand)["q_values"], got["q_values"], rtol=0, atol=1e-6)
    return got


def test_numpy_reproduces_predict_on_a_trained_checkpoint(trained_run, tmp_path):
    ckpt = trained_run.run_dir / "checkpoint"
    for route, step in (("right_turn", 0), ("right_turn", 12), ("straight_urban", 30)):
        got = check(ckpt, tmp_path, route, step)
        assert got["input"]["image"]["channels"] == 1 and got["input"]["scalar_names"] == ["speed/v0", "d/d0"]


@pytest.fixture
def rgb_path_features_checkpoint(tmp_path):
    config = TINY_TOML.replace("height = 16\n", "height = 24\nrgb = true\n").replace("conv_filters = 2", "conv_filters = 3\npath_features = true")
    learner = Learner(tmp_path / "rgb", config=config)
    learner.stop()  # writes a checkpoint of the seeded initial network
    return learner.run_dir / "checkpoint"


def test_numpy_reproduces_predict_with_rgb_frames_and_path_features(rgb_path_features_checkpoint, tmp_path):
    got = check(rgb_path_features_checkpoint, tmp_path, "left_turn", 25)
    assert got["input"]["image"]["channels"] == 3 and (got["input"]["image"]["height"], got["input"]["image"]["width"]) == (24, 16)
    assert len(got["input"]["scalars"]) == 5


# A vector checkpoint (no camera, `[env.vector]`): the hybrid-vector preset made tiny and fast.
TINY_VECTOR_TOML = """
preset = "{preset}"

[env.vector]
objects = 4
waypoints = 3
rays = 8

[env.traffic]
vehicles = 5

[agent]
hidden = 16
batch_size = 8
min_replay = 64
replay_capacity = 5000
replay_ratio = 0.5
publish_every_updates = 2

[service]
checkpoint_interval_secs = 3600
"""

MLP_TENSORS = {"fc1.weight", "fc1.bias", "fc2.weight", "fc2.bias", "q.weight", "q.bias"}


def vector_sizes(checkpoint_dir):
    """docs/MODEL.md's sizes of the vector network from config.toml: inputs, hidden, actions."""
    cfg = tomllib.loads((checkpoint_dir / "config.toml").read_text())
    v, agent = cfg["env"]["vector"], cfg["agent"]
    inputs = 3 + 13 * v["objects"] + 2 * v["rays"]
    if cfg["env"]["variant"] == "hybrid":
        inputs += 4 + 2 * v["waypoints"]
    return inputs, agent["hidden"], int("".join(filter(str.isdigit, agent["action_set"])))


def vector_q_values(checkpoint_dir, vector):
    """MODEL.md's VectorQ in NumPy: fc1, ReLU, fc2, ReLU, q over the reading as is."""
    p = {k: v.astype(np.float64) for k, v in load_file(checkpoint_dir / "online.safetensors").items()}
    h = np.maximum(p["fc1.weight"] @ np.asarray(vector, dtype=np.float64) + p["fc1.bias"], 0.0)
    h = np.maximum(p["fc2.weight"] @ h + p["fc2.bias"], 0.0)
    return p["q.weight"] @ h + p["q.bias"]


def torch_q_values():
    """MODEL.md's PyTorch recipe of the vector network (its `q_values`, loading strictly), or None
    where PyTorch is not installed (the CI machine)."""
    try:
        import torch  # noqa: F401
    except ImportError:
        return None
    text = (ROOT / "docs" / "MODEL.md").read_text()
    snippet = next(b for b in text.split("```python\n")[1:] if "class VectorQ" in b).split("```")[0]
    scope = {}
    exec(snippet, scope)
    return scope["q_values"]


def check_vector(checkpoint_dir, tmp_path, route, step):
    saved = tmp_path / f"{route}-{step}.json"
    got = predict("--checkpoint", checkpoint_dir, "--route", route, "--step", step, "--save-vector", saved)
    manifest = json.loads((checkpoint_dir / "manifest.json").read_text())
    assert got["input"]["vector"]["layout"] == manifest["vector_layout"]
    vector = json.loads(saved.read_text())
    inputs, _, actions = vector_sizes(checkpoint_dir)
    assert len(vector) == inputs and all(-1.0 <= x <= 1.0 for x in vector)
    # The reading is the network's input as is: no scaling besides the sensor's. (The file holds
    # float32s' shortest decimals, the JSON report the same float32s widened.)
    np.testing.assert_array_equal(np.float32(got["input"]["vector"]["values"]), np.float32(vector))
    np.testing.assert_array_equal(np.float32(got["input"]["scalars"]), np.float32(vector))
    q = vector_q_values(checkpoint_dir, vector)
    assert len(got["q_values"]) == actions
    np.testing.assert_allclose(got["q_values"], q, rtol=1e-5, atol=1e-6)
    assert got["greedy_action"] == int(np.argmax(q))
    # The saved reading fed back gives the same Q values.
    again = predict("--checkpoint", checkpoint_dir, "--vector", saved)
    np.testing.assert_array_equal(np.float32(again["input"]["scalars"]), np.float32(vector))
    np.testing.assert_allclose(again["q_values"], got["q_values"], rtol=0, atol=1e-6)
    assert again["greedy_action"] == got["greedy_action"]
    torch_q = torch_q_values()
    if torch_q is not None:
        np.testing.assert_allclose(torch_q(str(checkpoint_dir), vector).numpy(), got["q_values"], rtol=1e-5, atol=1e-6)
    return got


def check_mlp_tensors(checkpoint_dir):
    """The six tensors of MODEL.md's VectorQ and nothing else (what strict loading asks), with
    the shapes config.toml's sizes give."""
    inputs, hidden, actions = vector_sizes(checkpoint_dir)
    p = load_file(checkpoint_dir / "online.safetensors")
    assert set(p) == MLP_TENSORS
    shapes = {k: v.shape for k, v in p.items()}
    assert shapes == {"fc1.weight": (hidden, inputs), "fc1.bias": (hidden,), "fc2.weight": (hidden, hidden),
                      "fc2.bias": (hidden,), "q.weight": (actions, hidden), "q.bias": (actions,)}
    assert all(v.dtype == np.float32 for v in p.values())


@pytest.fixture(scope="module")
def trained_vector_checkpoint(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("vector")
    config = tmp / "tiny-vector.toml"
    config.write_text(TINY_VECTOR_TOML.format(preset="hybrid-vector"))
    done = actor_train(tmp / "run", "--config", config, "--max-env-steps", "600", "--eval-every", "0")
    assert done.returncode == 0, done.stderr
    return tmp / "run" / "checkpoint"


def test_numpy_reproduces_predict_on_a_trained_vector_checkpoint(trained_vector_checkpoint, tmp_path):
    ckpt = trained_vector_checkpoint
    state = json.loads((ckpt / "state.json").read_text())
    assert state["counters"]["learner_step"] > 0, "trained: the weights are not the initial ones"
    check_mlp_tensors(ckpt)
    for route, step in (("right_turn", 0), ("left_turn", 25), ("straight_urban", 30)):
        got = check_vector(ckpt, tmp_path, route, step)
        assert got["variant"] == "hybrid" and got["input"]["vector"]["layout"] == "vector/1 ego:1x3 path:1x4 waypoints:3x2 objects:4x13 rays:8x2"
        assert got["input"]["image"]["channels"] == 0


@pytest.fixture
def e2e_vector_checkpoint(tmp_path):
    learner = Learner(tmp_path / "e2e", config=TINY_VECTOR_TOML.format(preset="e2e-vector"))
    learner.stop()  # writes a checkpoint of the seeded initial network
    return learner.run_dir / "checkpoint"


def test_numpy_reproduces_predict_on_an_end_to_end_vector_checkpoint(e2e_vector_checkpoint, tmp_path):
    check_mlp_tensors(e2e_vector_checkpoint)
    got = check_vector(e2e_vector_checkpoint, tmp_path, "sharp_curve", 20)
    assert got["variant"] == "end_to_end" and got["input"]["vector"]["layout"] == "vector/1 ego:1x3 objects:4x13 rays:8x2"
