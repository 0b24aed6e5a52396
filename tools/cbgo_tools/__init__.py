"""cbgo's offline tools: benchmarks, training pipelines, cross-validation, data-set converters.

They sit on top of the library (`cbgo`) and the services (`cbgo.services`) and run from a
checkout (``pip install -e tools/``); the cbgo wheel and the Docker image carry none of them.
`cbgo_tools.registry` lists what `cbgo bench` and `cbgo train` run, `cbgo_tools.data` the data
sets behind `cbgo data`.
"""
