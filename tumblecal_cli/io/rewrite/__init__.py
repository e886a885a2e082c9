"""apply's writer: a capture written again with its sensor columns corrected and every other byte
kept. Its modules:

- ``writer``: the streaming writer, and which path each block takes (a plain block spliced
  by ``io.csv.splice``).
- ``forked``: a big file's blocks corrected by forked worker processes, one per core."""
