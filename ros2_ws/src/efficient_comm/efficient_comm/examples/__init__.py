"""Example components and the demo pipeline (``python -m efficient_comm.examples.demo``)."""
