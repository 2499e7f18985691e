"""The peer of crates/mbs-mpi/examples/allreduce.rs: PyTorch's
torch.distributed all_reduce (the gloo backend, what DistributedDataParallel
uses on CPUs) of one f32 buffer as long as RAFT-Stereo's and IGEV-Stereo's
gradients, between 2 processes on loopback.

    .venv-test/bin/python tools/bench/allreduce_torch.py RAFT_PARAMS IGEV_PARAMS [REPEATS]

(the parameter counts the Rust example prints). Rank 0 prints the median,
min and max milliseconds.
"""

import os
import statistics
import sys
import time

import torch
import torch.distributed as dist
import torch.multiprocessing as mp


def run(rank, sizes, repeats):
    os.environ["MASTER_ADDR"] = "127.0.0.1"
    os.environ["MASTER_PORT"] = "29517"
    torch.set_num_threads(1)
    dist.init_process_group("gloo", rank=rank, world_size=2)
    for name, size in sizes:
        buffer = torch.ones(size, dtype=torch.float32)
        times = []
        for _ in range(repeats + 2):
            dist.barrier()
            start = time.perf_counter()
            dist.all_reduce(buffer)
            times.append((time.perf_counter() - start) * 1e3)
        kept = sorted(times[2:])
        if rank == 0:
            print(
                f"{name}: {size} parameters, gloo all_reduce median {statistics.median(kept):.1f} ms "
                f"(min {kept[0]:.1f}, max {kept[-1]:.1f})",
                flush=True,
            )
    dist.destroy_process_group()


if __name__ == "__main__":
    raft, igev = int(sys.argv[1]), int(sys.argv[2])
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 20
    mp.spawn(run, args=([("RaftStereo", raft), ("Igev", igev)], repeats), nprocs=2)
