"""How the host builds the FMUs (Python-hosted, standalone and native): model descriptions, bundle, stub compilation and archives; nothing here runs inside an FMU."""
