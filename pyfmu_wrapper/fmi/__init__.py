"""The FMUs: their declaration, what runs inside them (Python-hosted or native) and how the host builds them."""
