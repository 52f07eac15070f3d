# Sourced by the scripts: MPI settings for this machine (containers run as root; no
# oversubscription errors on 2 cores; no noisy transports).
export OMPI_ALLOW_RUN_AS_ROOT=1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none
