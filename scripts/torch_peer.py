#!/usr/bin/env python3
"""The paper's Q-network in PyTorch (channels-last), timed as `learner bench train` times fastnet:
a full DQN update at batch 32 (online forward, target forward on the next states, smooth-L1 loss,
backward, Adam) and a batch-1 forward, in f32 and in bf16 autocast (oneDNN; AMX where present), on
2 threads. Prints one JSON object. Usage: torch_peer.py SIZE CHANNELS [--updates N].

With `--vector N` (SIZE and CHANNELS are then ignored, e.g. 0 0) the network is the multilayer
perceptron of a vector input, as fastnet's shape with no image: N inputs (values in [-1, 1]) →
Linear(N, HIDDEN) → ReLU → Linear(HIDDEN, HIDDEN) → ReLU → Linear(HIDDEN, ACTIONS), at `--batch`
(default 256 for it) with `--actions` (default 27) and `--hidden` (256).

Adapted from the workplace's measuring aid (../shared/tools/torch_dqn_peer.py); used by
scripts/bench-vs-torch.sh to put PyTorch beside fastnet in the same run.
"""
import argparse
import json
import statistics
import time

import torch
import torch.nn as nn

p = argparse.ArgumentParser()
p.add_argument("size", type=int)
p.add_argument("channels", type=int)
p.add_argument("--updates", type=int, default=20)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--vector", type=int, default=0, help="the MLP over this many inputs instead")
p.add_argument("--batch", type=int, default=None)
p.add_argument("--actions", type=int, default=None)
p.add_argument("--hidden", type=int, default=256)
args = p.parse_args()
torch.set_num_threads(args.threads)
S, C, V, H = args.size, args.channels, args.vector, args.hidden
B = args.batch or (256 if V else 32)
A = args.actions or (27 if V else 6)


class Net(nn.Module):
    def __init__(self):
        super().__init__()
        conv = lambda cin: [nn.Conv2d(cin, 64, 3, padding=1), nn.ReLU(), nn.AvgPool2d(2)]
        self.c = nn.Sequential(*conv(C), *conv(64), *conv(64))
        n = 64 * (S // 8) ** 2
        self.f = nn.Sequential(nn.Linear(n + 2, H), nn.ReLU(), nn.Linear(H, H), nn.ReLU(), nn.Linear(H, A))

    def forward(self, x, y):
        return self.f(torch.cat([self.c(x).flatten(1), y], 1))


class Mlp(nn.Module):
    """fastnet's network with no image: fc1, fc2 and q over the vector alone."""

    def __init__(self):
        super().__init__()
        self.f = nn.Sequential(nn.Linear(V, H), nn.ReLU(), nn.Linear(H, H), nn.ReLU(), nn.Linear(H, A))

    def forward(self, x, y):
        return self.f(y)


def median_ms(f, n):
    for _ in range(3):
        f()
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        f()
        ts.append((time.perf_counter() - t0) * 1000)
    return statistics.median(ts)


name = f"vector:{V}" if V else f"{S}x{S}x{C}"
out = {"input": name, "threads": args.threads, "torch": torch.__version__, "batch": B, "actions": A, "hidden": H}
for dt in [None, torch.bfloat16]:
    torch.manual_seed(0)
    if V:
        net, tgt = Mlp(), Mlp()
        x, x1 = torch.empty(B, 0), torch.empty(1, 0)
        y, y1 = torch.rand(B, V) * 2 - 1, torch.rand(1, V) * 2 - 1
    else:
        net = Net().to(memory_format=torch.channels_last)
        tgt = Net().to(memory_format=torch.channels_last)
        x = torch.rand(B, C, S, S).to(memory_format=torch.channels_last)
        x1 = torch.rand(1, C, S, S).to(memory_format=torch.channels_last)
        y, y1 = torch.rand(B, 2), torch.rand(1, 2)
    opt = torch.optim.Adam(net.parameters(), 1e-4)
    a = torch.randint(0, A, (B,))
    r = torch.rand(B)

    def step():
        with torch.autocast("cpu", dtype=dt, enabled=dt is not None):
            q = net(x, y).gather(1, a[:, None]).squeeze(1)
            with torch.no_grad():
                t = r + 0.99 * tgt(x, y).max(1).values
            loss = nn.functional.smooth_l1_loss(q.float(), t.float())
        opt.zero_grad()
        loss.backward()
        opt.step()

    def fwd():
        with torch.inference_mode(), torch.autocast("cpu", dtype=dt, enabled=dt is not None):
            net(x1, y1)

    name = "bf16" if dt else "f32"
    out[name] = {"ms_per_update": median_ms(step, args.updates), "forward_batch1_ms": median_ms(fwd, 100)}
print(json.dumps(out))
