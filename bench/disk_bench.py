"""Disk benchmark: what a loaded program takes on disk, after compaction, and what takes the space.

    pip install -e '.[bench]' && python bench/disk_bench.py            # 100k instances, both programs
    python bench/disk_bench.py --sizes 10000 100000 --programs replicated

For each size and program (bench/generate.py's ``generated`` one, a ``replicated`` real one: copies of
the shipped two-setup shaft unless ``--real`` names another): a load into a fresh on-disk store, then
``compact`` (a rebuild of the database from its graphs, as `stepnc-graph compact` does), then:

* the store on disk against the Part 21 file (issue-32 target: at most 20 times its size), split
  into the database (the published generation), the kept texts (each graph's last loaded text,
  compressed: what a re-load compares against) and the rest;
* the database by RocksDB column family -- Oxigraph's string table (``id2str``: IRIs and long
  literals), its quad indexes (``spog`` ... ``gosp``: six orders of every quad in a named graph)
  and the others -- read from the table files' own properties: bytes on disk, entries, the raw key
  bytes, the compression the table was written with;
* the quads by graph (the program, its derived layer, the vocabulary), the predicates with the most
  quads, and bytes on disk per quad;
* reference: a fresh pyoxigraph store holding the same N-Quads by ``bulk_load`` (and then
  ``optimize``), the same for the program's graph alone (so the derived layer's and the
  vocabulary's share is measured, not estimated), and the N-Quads text with its gzip size.

The figures are sizes, not times: the machine's load does not change them.
"""

from __future__ import annotations

import argparse
import gzip
import os
import shutil
import struct
import sys
import tempfile
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from generate import program_file  # noqa: E402

TARGET = 20.0
#: Oxigraph's column families: what each holds
FAMILIES = {
    "id2str": "strings: IRIs and literals too long to inline",
    "spog": "index, named graphs: subject-predicate-object-graph", "posg": "index: predicate-object-subject-graph",
    "ospg": "index: object-subject-predicate-graph", "gspo": "index: graph-subject-predicate-object",
    "gpos": "index: graph-predicate-object-subject", "gosp": "index: graph-object-subject-predicate",
    "dspo": "index, default graph: s-p-o", "dpos": "index, default graph: p-o-s", "dosp": "index, default graph: o-s-p",
    "graphs": "the named graphs", "default": "RocksDB's default family",
}


# -- RocksDB table properties ----------------------------------------------------------------------


def _varint(data: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[i]
        i += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, i


def _entries(block: bytes) -> dict[bytes, bytes]:
    """The key/value entries of an uncompressed block-based-table block (prefix-compressed keys)."""
    restarts = struct.unpack("<I", block[-4:])[0]
    end, i, key, out = len(block) - 4 - 4 * restarts, 0, b"", {}
    while i < end:
        shared, i = _varint(block, i)
        unshared, i = _varint(block, i)
        size, i = _varint(block, i)
        key = key[:shared] + block[i:i + unshared]
        i += unshared
        out[key] = block[i:i + size]
        i += size
    return out


def table_properties(path: Path) -> dict[bytes, bytes]:
    """The properties block of a RocksDB table file (footer format 5, or 6 and later)."""
    with open(path, "rb") as f:
        f.seek(0, 2)
        size = f.tell()
        f.seek(size - 53)
        footer = f.read(53)
        version = struct.unpack("<I", footer[-12:-8])[0]
        if version >= 6:  # the metaindex block sits right before the footer; its size is in it
            meta_size = struct.unpack("<I", footer[13:17])[0]
            meta_offset = size - 53 - 5 - meta_size
        else:
            meta_offset, i = _varint(footer, 1)
            meta_size, _ = _varint(footer, i)
        f.seek(meta_offset)
        handle = _entries(f.read(meta_size)).get(b"rocksdb.properties")
        if handle is None:
            return {}
        offset, i = _varint(handle, 0)
        length, _ = _varint(handle, i)
        f.seek(offset)
        return _entries(f.read(length))


def families(directory: Path) -> dict[str, dict[str, Any]]:
    """Bytes, entries, raw key bytes and compressions of the tables under ``directory``, by column
    family (tables written by an SST writer and ingested carry no family name: ``(ingested)``)."""
    out: dict[str, dict[str, Any]] = defaultdict(lambda: {"bytes": 0, "entries": 0, "raw": 0, "compression": set()})
    for path in directory.glob("*.sst"):
        props = table_properties(path)
        name = props.get(b"rocksdb.column.family.name", b"(ingested)").decode() or "(ingested)"
        row = out[name]
        row["bytes"] += path.stat().st_blocks * 512
        row["entries"] += _varint(props.get(b"rocksdb.num.entries", b"\0"), 0)[0]
        row["raw"] += (_varint(props.get(b"rocksdb.raw.key.size", b"\0"), 0)[0]
                       + _varint(props.get(b"rocksdb.raw.value.size", b"\0"), 0)[0])
        compression = props.get(b"rocksdb.compression", b"?").decode(errors="replace")
        row["compression"].add(compression if compression.isalnum() else "?")
    return dict(out)


# -- the measurements -----------------------------------------------------------------------------


def du(path: Path) -> int:
    from stepnc_graph.store import directory_bytes

    return directory_bytes(path) if path.exists() else 0


def bulk_store_bytes(text: Path, work: Path, graph: str | None = None) -> tuple[int, dict[str, dict[str, Any]]]:
    """A fresh pyoxigraph store holding ``text`` (N-Quads; with ``graph``, N-Triples loaded into that
    named graph), bulk-loaded, then optimized: its bytes on disk and its column families."""
    import pyoxigraph as ox

    where = work / f"bulk-{text.stem}"
    store = ox.Store(str(where))
    if graph is None:
        store.bulk_load(path=str(text), format=ox.RdfFormat.N_QUADS)
    else:
        store.bulk_load(path=str(text), format=ox.RdfFormat.N_TRIPLES, to_graph=ox.NamedNode(graph))
    store.optimize()
    store.flush()
    del store
    size, cf = du(where), families(where)
    shutil.rmtree(where, ignore_errors=True)
    return size, cf


def measure(program: str, path: Path, work: Path) -> None:
    import pyoxigraph as ox

    import stepnc_graph as sg
    from stepnc_graph.core.naming import VOCABULARY_GRAPH, derived_graph_iri

    store_dir = work / "store"
    with sg.open_store(store_dir) as store:
        [result] = sg.load(store, [path])
        loaded = store.disk_bytes()
        store.compact()
        graph = result.graph
        graphs = {"program": graph, "derived layer": derived_graph_iri(graph), "vocabulary": VOCABULARY_GRAPH}
        quads = {k: store.count(g) for k, g in graphs.items()}
        predicates = {k: Counter(q.predicate.value for q in store.quads(g)) for k, g in graphs.items() if k != "vocabulary"}
        everything, alone = work / "all.nq", work / "program.nt"
        with open(everything, "wb") as out:
            store.oxigraph.dump(out, ox.RdfFormat.N_QUADS)
        with open(alone, "wb") as out:
            store.oxigraph.dump(out, ox.RdfFormat.N_TRIPLES, from_graph=ox.NamedNode(graph))
    file_bytes = path.stat().st_size
    generation = (store_dir / "CURRENT").read_text().strip()
    database, kept = du(store_dir / generation), du(store_dir / "kept")
    total = du(store_dir)
    cf = families(store_dir / generation)
    (same_quads, same_cf), (program_only, _) = bulk_store_bytes(everything, work), bulk_store_bytes(alone, work, graph)
    text = everything.stat().st_size
    gz = len(gzip.compress(everything.read_bytes(), compresslevel=6))
    everything.unlink()
    alone.unlink()
    n = sum(quads.values())
    mb = 1e6
    print(f"\n== {program} program, {result.instances:,} instances: Part 21 file {file_bytes / mb:.1f} MB")
    print(f"  store after the load {loaded / mb:8.1f} MB ({loaded / file_bytes:5.1f}x the file)")
    print(f"  store after compact  {total / mb:8.1f} MB ({total / file_bytes:5.1f}x the file; target <= {TARGET:.0f}x: "
          f"{'ok' if total / file_bytes <= TARGET else f'MISS by {total / file_bytes / TARGET:.1f}x'})")
    print(f"    database           {database / mb:8.1f} MB ({100 * database / total:4.1f} %), {database / n:5.0f} bytes a quad")
    print(f"    kept texts         {kept / mb:8.1f} MB ({100 * kept / total:4.1f} %)")
    print(f"    other              {(total - database - kept) / mb:8.1f} MB")
    print("  database by column family (from the tables' properties):")
    for name, row in sorted(cf.items(), key=lambda kv: -kv[1]["bytes"]):
        print(f"    {name:11} {row['bytes'] / mb:8.1f} MB {row['entries']:>11,} entries, {row['raw'] / mb:8.1f} MB raw, "
              f"{'/'.join(sorted(row['compression']))}  {FAMILIES.get(name, '')}")
    indexes = sum(row["bytes"] for name, row in cf.items() if name not in ("id2str", "graphs", "default"))
    print(f"    quad indexes {indexes / mb:.1f} MB: {indexes / n:.0f} bytes a quad ({indexes / n / 6:.0f} per index entry)")
    print(f"  quads: {n:,} ({n / result.instances:.1f} an instance): " +
          ", ".join(f"{k} {v:,} ({100 * v / n:.0f} %)" for k, v in quads.items()))
    for kind, counts in predicates.items():
        top = counts.most_common(6)
        print(f"    {kind}: " + ", ".join(f"{p.rsplit('#', 1)[-1].rsplit('/', 1)[-1]} {c:,}" for p, c in top))
    compressions = "/".join(sorted({c for row in same_cf.values() for c in row["compression"]}))
    print(f"  reference: pyoxigraph store of the same quads (bulk_load + optimize; tables {compressions}) "
          f"{same_quads / mb:.1f} MB ({same_quads / file_bytes:.1f}x the file); of the program's graph alone "
          f"{program_only / mb:.1f} MB ({program_only / file_bytes:.1f}x): derived layer and vocabulary "
          f"{(same_quads - program_only) / mb:.1f} MB")
    print(f"  the same quads as N-Quads text {text / mb:.1f} MB ({text / file_bytes:.1f}x), gzip {gz / mb:.1f} MB "
          f"({gz / file_bytes:.2f}x)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000])
    ap.add_argument("--programs", nargs="+", choices=["generated", "replicated"], default=["generated", "replicated"])
    ap.add_argument("--real", type=Path, default=HERE.parent / "examples" / "shaft_two_setups.stp")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    args = ap.parse_args()
    args.data.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} cores; Python {sys.version.split()[0]}")
    for size in args.sizes:
        for program in args.programs:
            path = program_file(args.data, program, size, args.real)
            work = Path(tempfile.mkdtemp(prefix="stepnc-disk-bench-", dir=args.data))
            try:
                measure(program, path, work)
            finally:
                shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
