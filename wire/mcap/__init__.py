"""MCAP logs: `writer` (McapLogWriter: crash-safe, chunked, rotating), `reader` (messages and summaries of
complete or cut files), `fast` (the mcap Writer with a faster add_message), `rotation` (file names of a
rotated set), `format` (record layout facts of the MCAP specification)."""
