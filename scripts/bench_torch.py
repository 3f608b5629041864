#!/usr/bin/env python3
"""PyTorch eager on the paper network's weights: the side-by-side for `cargo bench --bench lstm`.

Builds the same network as src/model/lstm.rs (nn.LSTM(21, 128, num_layers=2,
bidirectional=True, batch_first=True), last layer's final forward/backward hidden states,
dropout, nn.Linear(256, 3), tanh), loads config/models/lstm-m100-h128/model.safetensors
(the paper's network, shipped before the ensemble; same variable names), checks it is the
same network, then times one window and a batch of 256 (medians of 200 and 50 runs, one thread unless BENCH_THREADS says otherwise).

    scripts/setup-torch-bench.sh && .venv-bench/bin/python scripts/bench_torch.py [MODEL_DIR]

Needs a PyTorch that imports, and numpy: `.venv-bench` (PyPI's torch 2.13.0 with its CUDA
libraries; it runs on the CPU). `.venv-torch` holds only the libtorch dronewatt links and
cannot `import torch`.
"""
import json
import os
import statistics
import struct
import sys
import time

import numpy as np
import torch

DTYPES = {"F32": np.float32, "F64": np.float64, "I64": np.int64}


def read_safetensors(path):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    out = {}
    for name, meta in header.items():
        if name == "__metadata__":
            continue
        a, b = meta["data_offsets"]
        arr = np.frombuffer(data[a:b], dtype=DTYPES[meta["dtype"]]).reshape(meta["shape"])
        out[name] = torch.from_numpy(arr.copy())
    return out


class Net(torch.nn.Module):
    def __init__(self, hidden=128, layers=2):
        super().__init__()
        self.lstm = torch.nn.LSTM(21, hidden, num_layers=layers, bidirectional=True, batch_first=True)
        self.head = torch.nn.Linear(2 * hidden, 3)
        self.dropout = torch.nn.Dropout(0.5)

    def forward(self, x):
        _, (h, _) = self.lstm(x)
        last = torch.cat([h[-2], h[-1]], dim=1)
        return torch.tanh(self.head(self.dropout(last)))


def median_us(fn, runs):
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e6


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else "config/models/lstm-m100-h128"
    torch.set_num_threads(int(os.environ.get("BENCH_THREADS", "1")))
    net = Net()
    net.load_state_dict(read_safetensors(os.path.join(d, "model.safetensors")))
    net.eval()
    one = torch.randn(1, 10, 21)
    batch = torch.randn(256, 10, 21)
    with torch.no_grad():
        for _ in range(20):
            net(one)
        single = median_us(lambda: net(one), 200)
        b256 = median_us(lambda: net(batch), 50)
    print(f"pytorch {torch.__version__} eager, {torch.get_num_threads()} thread(s): "
          f"single window {single:.0f} us, batch 256 {b256 / 1000:.2f} ms ({256e6 / b256:.0f} windows/s)")


if __name__ == "__main__":
    main()
