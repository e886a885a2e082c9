"""What people look at (the optional extra ``tumblecal[plot]``, matplotlib imported inside the
functions). Its modules:

- ``plots``: PNG figures of rotation captures, lots, thermal sweeps and noise, and how every
  figure is drawn and written.
- ``fitplots``: PNG figures that judge a fit: ``solve --plot``, ``verify --plot`` and
  ``segment --plot``.
- ``lothtml``: ``report --html``, the lot report as one self-contained HTML page.
- ``trendhtml``: ``records trend --html``, the stations' alarms and their control charts (SVG) as
  one self-contained page."""
