"""Campaigns: many sessions under conditions a lab chooses, compared with honest intervals.

A table of sessions (`table`), each an independent task run on Dask with a cache (`session`,
`cache`, `tasks`), compared across conditions with a random-effects model (`stats`,
`compare`), written as tidy tables, JSON (`results`) and an HTML page (`report`). ROS-free.
"""
