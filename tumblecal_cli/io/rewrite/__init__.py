"""apply's writer: a capture written again with its sensor columns corrected and every other byte
kept. Its modules:

- ``writer``: the streaming writer, and which path each block takes.
- ``splice``: the fast path, corrected sensor cells spliced into a plain file's own bytes.
- ``forked``: a big file's blocks corrected by forked worker processes, one per core."""
