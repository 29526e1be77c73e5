"""The store's measured tuning: batch sizes, cost figures and the compaction policy.

Each constant keeps one line of reason here; the measurements that chose it are in docs/loading.md
("The store's tuning, measured"). The store reads them as ``tuning.NAME`` when it runs, so a test
or a benchmark may set one for a run.
"""

from __future__ import annotations

import os

#: threads that bulk-load, dump or delete side by side (Oxigraph releases the GIL in them) (docs/loading.md)
LOAD_THREADS = max(1, min(4, os.cpu_count() or 1))

#: N-Triples characters per bulk_load call: the bulk loader's memory grows with a call (docs/loading.md)
BATCH_CHARS = 12_000_000

#: a chunk this large is bulk-loaded from bytes: the streaming reader stops at lines over 16 MiB (docs/loading.md)
DIRECT_CHARS = 8_000_000

#: characters per bytes batch of an in-memory load (from a stream the loader holds the GIL) (docs/loading.md)
MEMORY_BATCH_CHARS = 4_000_000

#: µs of CPU a quad to delete it, and to copy it into a rebuilt database: they choose how a graph is removed (docs/loading.md)
DELETE_COST, REBUILD_COST = 11.0, 10.0

#: quads a delete transaction removes (docs/loading.md)
DELETE_BATCH = 100_000

#: deleted quads after which batched deletes flush RocksDB's memory tables (docs/loading.md)
FLUSH_DELETES = 500_000

#: an unload compacts once the quads deleted since the last compaction reach this share of the store (docs/loading.md)
COMPACT_AT = 0.35

#: quads per bulk_extend call of a rebuild (docs/loading.md)
REBUILD_BATCH = 250_000

#: a replacement by difference stages the new version in memory up to this many old quads, else on disk (docs/loading.md)
STAGE_IN_MEMORY_QUADS = 3_000_000

#: bytes of one graph's old N-Triples lines compared at a time (larger dumps are split by a hash of each line) (docs/loading.md)
COMPARE_BYTES = 128 << 20

#: quads per bulk call when a replacement by difference inserts what changed (docs/loading.md)
INSERT_BATCH = 250_000

#: quads that add_quads writes in one transaction (more go through the bulk loader) (docs/loading.md)
TRANSACTION_QUADS = 25_000

#: quads per DELETE DATA request of a replacement by difference (docs/loading.md)
DELETE_LINES = 20_000
