"""CSV captures (docs/reference/csv.md). Its modules:

- ``sniff``: a capture's layout decided from its head: delimiter, header, preamble, decimal
  mark, and which columns hold the sensor triplet, the time and the temperature.
- ``compressed``: gzip, bzip2, xz and Zstandard captures read as they are, and written so.
- ``capture``: a capture streamed through pyarrow with every cell's text kept, its errors
  located by line and column.
- ``readings``: pose files and whole logs read into memory (``Samples``, ``Log``), with their
  clock's unit judged.
- ``posefile``: a pose file judged by running sums, in memory that does not grow with it.
- ``logread``: a long log read block by block into the streaming still-block detector
  (``core.scan``), for segment and solve --log.
- ``splice``: a plain file's blocks of whole lines, found by reading their ends only (``cuts``),
  and their sensor cells parsed, or replaced in the block's own bytes, without the other cells
  (apply's fast path, and the log reader's).
- ``ahead``: a stream's next blocks worked on a thread of their own while its last is used."""
