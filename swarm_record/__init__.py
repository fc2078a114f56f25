"""The recording of a run (``swarm-up --record``): the recorder process
(:mod:`swarm_record.recorder`), the MCAP file's contract and format
(:mod:`swarm_record.mcap_format`, pure) and ``swarm-plot`` (:mod:`swarm_record.plot`)."""
