"""What a user does, composed from io and core: the public Python API (``tumblecal_cli.__all__``)
that the commands, ``batch`` and the Dask workers call. pandas only inside the functions that take
or return DataFrames."""
