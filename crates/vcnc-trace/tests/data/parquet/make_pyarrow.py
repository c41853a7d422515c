"""Writes pyarrow.parquet (the writer pandas and most Python tools use) and its CSV twin.

Run with pyarrow 26 (pip install pyarrow numpy): python3 make_pyarrow.py
The table is a made-up 1 kHz recording of one axis, in the column types data tools write:
nullable DOUBLE (pandas' float64, dictionary-encoded by default), FLOAT, INT64 and UINT16,
in row groups of 128 rows with version-2 data pages. The CSV holds the same values written
exactly (every FLOAT as the double it widens to), so the two must read alike.
"""
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

n = 300
t = np.arange(n) * 1e-3 + 0.25
ref = 10.0 * np.sin(2.0 * np.pi * 1.5 * t)
act = (ref - 0.002 * np.cos(2.0 * np.pi * 1.5 * t)).astype(np.float32)
count = np.arange(n, dtype=np.int64) * 3 - 400
status = (np.arange(n) * 257 % 65536).astype(np.uint16)
table = pa.table(
    {
        "t": t,
        "X_ref [mm]": ref,
        "X_act [mm]": act,
        "count": count,
        "status": pa.array(status, type=pa.uint16()),
    }
)
pq.write_table(table, "pyarrow.parquet", row_group_size=128, data_page_version="2.0")
with open("pyarrow.csv", "w") as f:
    f.write("t,X_ref [mm],X_act [mm],count,status\n")
    for k in range(n):
        row = [repr(float(t[k])), repr(float(ref[k])), repr(float(act[k])), str(count[k]), str(status[k])]
        f.write(",".join(row) + "\n")

# A codec vcnc does not read (polars' default): refused naming it and what to write instead.
pq.write_table(table.slice(0, 10), "zstd.parquet", compression="zstd")
