# tools/module.mk - developer and report tools. Included by the top Makefile.
