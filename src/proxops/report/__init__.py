"""Run and campaign reports (tables + figures): the layer above analysis and plotting."""
