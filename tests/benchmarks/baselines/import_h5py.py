"""Baseline: what a user writes to put a CSV table into HDF5, pandas and bare h5py.

    python import_h5py.py TABLE.csv OUT.h5 [GZIP_LEVEL]

One dataset per column, gzip (level 1 unless given), text columns as fixed-length bytes.  No
labcli import: the benchmarks time this beside ``labcli import`` as the independent baseline.
"""

import sys

import h5py
import pandas as pd


def main():
    src, out = sys.argv[1], sys.argv[2]
    level = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    df = pd.read_csv(src)
    with h5py.File(out, "w") as f:
        for name in df.columns:
            values = df[name].to_numpy()
            if values.dtype.kind not in "biuf":
                values = values.astype("S")
            f.create_dataset(name, data=values, compression="gzip", compression_opts=level)


if __name__ == "__main__":
    main()
